#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = glint::mesh::parse_mtl(data, std::path::Path::new("fuzz.mtl"));
});
