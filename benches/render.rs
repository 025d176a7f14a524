//! `cargo bench`: median render times of every classic scene (when
//! ../shared/scenes/classic exists) and every scene in scenes/, on the best
//! Vulkan device (if any) and the CPU reference in f32 and f64. The same
//! measurement as `glint bench --f64`; see src/bench.rs.

use glint::suites::bench::{default_scenes, run, BenchOptions};

fn main() {
    // `cargo bench` runs from the package root.
    let scenes = default_scenes(&mut |note| eprintln!("SKIPPED: {note}"));
    let gpu = glint::gpu::list_devices().is_ok_and(|d| !d.is_empty());
    if !gpu {
        eprintln!("SKIPPED: GPU column (no Vulkan device)");
    }
    let options = BenchOptions {
        scenes,
        width: 640,
        height: 480,
        repeat: 7,
        gpu,
        cpu_f32: true,
        cpu_f64: true,
        device: None,
        uniform_lists: true,
        // This binary is the bench harness, not glint.
        end_to_end: None,
    };
    let report = run(&options, &mut |line| eprintln!("{line}")).expect("benchmark runs");
    println!("{}", report.to_markdown());
}
