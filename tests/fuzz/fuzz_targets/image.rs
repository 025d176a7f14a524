#![no_main]
// The images `compare`, `stitch` and `accuracy --reference` read, in each
// format glint names by extension, and the part stamp `stitch` and a
// re-run `render --part` read from a PNG's text or an EXR's header.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    for name in ["fuzz.png", "fuzz.jpg", "fuzz.ppm", "fuzz.exr"] {
        let path = std::path::Path::new(name);
        let _ = glint::images::framebuffer::decode_image(data, path);
        let _ = glint::parts::stamp::stamp_of(data, path);
    }
});
