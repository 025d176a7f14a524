#![no_main]
// The images `compare`, `stitch` and `accuracy --reference` read, in each
// format glint names by extension.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    for name in ["fuzz.png", "fuzz.jpg", "fuzz.ppm", "fuzz.exr"] {
        let _ = glint::framebuffer::decode_image(data, std::path::Path::new(name));
    }
});
