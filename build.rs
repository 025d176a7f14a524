//! Compiles shaders/*.wgsl to SPIR-V with naga at build time, so a broken
//! shader fails `cargo build` with the shader's file, line and column.
//!
//! Each shader is written once per variant: its `override` constants resolved
//! by naga's `process_overrides` (Vulkan specialization constants never reach
//! naga's SPIR-V), so every variant holds only the code paths it uses.

use std::path::Path;

use naga::back::spv;
use naga::proc::{BoundsCheckPolicies, BoundsCheckPolicy};
use naga::valid::{Capabilities, ValidationFlags, Validator};

const SHADERS: &[&str] = &["trace"];
/// (file suffix, override values) of each variant; src/gpu/pipeline.rs loads
/// them by suffix.
const VARIANTS: &[(&str, &[(&str, f64)])] = &[
    ("robust", &[("ROBUST", 1.0)]),
    ("naive", &[("ROBUST", 0.0)]),
];

fn main() {
    let out_dir = std::env::var("OUT_DIR").expect("cargo sets OUT_DIR");
    for name in SHADERS {
        let path = format!("shaders/{name}.wgsl");
        println!("cargo:rerun-if-changed={path}");
        let source =
            std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("cannot read {path}: {e}"));
        for (suffix, overrides) in VARIANTS {
            let words = compile(&source, &path, overrides).unwrap_or_else(|message| {
                // Cargo shows a build script's stderr on failure; exit rather
                // than panic so the message is not buried under a backtrace.
                eprintln!("{message}");
                std::process::exit(1);
            });
            let spv_path = Path::new(&out_dir).join(format!("{name}_{suffix}.spv"));
            std::fs::write(&spv_path, bytemuck_words(&words))
                .unwrap_or_else(|e| panic!("cannot write {}: {e}", spv_path.display()));
        }
    }
}

fn compile(source: &str, path: &str, overrides: &[(&str, f64)]) -> Result<Vec<u32>, String> {
    let module = naga::front::wgsl::parse_str(source).map_err(|e| {
        format!(
            "shader parse error\n{}",
            e.emit_to_string_with_path(source, path)
        )
    })?;
    let info = Validator::new(ValidationFlags::all(), Capabilities::empty())
        .validate(&module)
        .map_err(|e| {
            format!(
                "shader validation error\n{}",
                e.emit_to_string_with_path(source, path)
            )
        })?;
    let mut constants = naga::back::PipelineConstants::default();
    for (name, value) in overrides {
        constants.insert(name.to_string(), *value);
    }
    let (module, info) =
        naga::back::pipeline_constants::process_overrides(&module, &info, None, &constants)
            .map_err(|e| format!("{path}: resolving overrides {overrides:?}: {e}"))?;
    let options = spv::Options {
        // SPIR-V 1.0 runs on every Vulkan 1.0 device, MoltenVK included.
        lang_version: (1, 0),
        flags: spv::WriterFlags::empty(),
        // Every index the shader uses comes from our own BVH builder; Restrict
        // (clamp) still keeps a builder bug from reading out of bounds, at the
        // cost of a min() per access (not measurable on lavapipe).
        bounds_check_policies: BoundsCheckPolicies {
            index: BoundsCheckPolicy::Restrict,
            buffer: BoundsCheckPolicy::Restrict,
            image_load: BoundsCheckPolicy::Restrict,
            binding_array: BoundsCheckPolicy::Restrict,
        },
        // A loop the compiler may assume finite must be finite; naga's counter
        // makes that hold even for a traversal bug, which the host's fence
        // timeout then reports instead of a hung device. Measured cost on
        // lavapipe: ~8% of SIGGRAPH's median render (553 vs 599 ms), inside
        // the run-to-run spread.
        force_loop_bounding: true,
        // Without a binding map naga writes each @group/@binding as declared.
        fake_missing_bindings: true,
        ..spv::Options::default()
    };
    // No pipeline options: every entry point goes into the one module.
    spv::write_vec(&module, &info, &options, None)
        .map_err(|e| format!("{path}: SPIR-V generation failed: {e}"))
}

fn bytemuck_words(words: &[u32]) -> Vec<u8> {
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}
