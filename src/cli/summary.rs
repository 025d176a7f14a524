//! The end-of-render summary `render --stats` and `-v` print: rays by kind
//! and per second, GPU and CPU time, samples, the BVH, time per phase and
//! peak memory.

use std::time::Duration;

/// The end-of-render summary (`--stats`, `-v`).
pub fn stats(output: &glint::render::RenderOutput, timings: &glint::timing::Timings) -> String {
    use glint::timing::{CLOSEST_RAYS, SHADOW_RAYS, UNTRACED_SHADOW_RAYS};
    let mut s = String::from("stats:");
    let rendering = timings
        .phases
        .iter()
        .filter(|(n, _)| matches!(*n, "dispatch" | "readback" | "cpu render"))
        .map(|p| p.1)
        .sum::<Duration>();
    if timings.has_count(CLOSEST_RAYS) {
        let closest = timings.counted(CLOSEST_RAYS);
        let shadow = timings.counted(SHADOW_RAYS);
        // Every sample casts one primary ray; the other closest-hit rays
        // are reflections.
        let primary = output.samples.min(closest);
        let all = closest + shadow;
        let rate = all as f64 / rendering.as_secs_f64().max(1e-9);
        s.push_str(&format!(
            "\n  rays        {all} in all: {primary} primary, {} reflected, {shadow} shadow; \
             {:.2} M rays/s over {:.3} s of rendering",
            closest - primary,
            rate / 1e6,
            rendering.as_secs_f64()
        ));
        let untraced = timings.counted(UNTRACED_SHADOW_RAYS);
        if untraced > 0 {
            s.push_str(&format!(
                "\n  untraced    {untraced} shadow rays: whether they were blocked could not \
                 change a pixel"
            ));
        }
    } else {
        s.push_str(
            "\n  rays        not counted: one pass could cast more than the shader's 32-bit \
             counters hold (lower --pass-budget or --tile to count them)",
        );
    }
    if timings.has_count(glint::timing::GPU_TIME_NS) {
        s.push_str(&format!(
            "\n  gpu time    {:.3} ms in the dispatches (Vulkan timestamps)",
            timings.counted(glint::timing::GPU_TIME_NS) as f64 / 1e6
        ));
    }
    if timings.has_count(glint::timing::CPU_TIME_NS) {
        s.push_str(&format!(
            "\n  cpu time    {:.3} ms on the render's threads, all together",
            timings.counted(glint::timing::CPU_TIME_NS) as f64 / 1e6
        ));
    }
    for name in [glint::timing::READBACK_BYTES, glint::timing::UPLOADED_BYTES] {
        if timings.has_count(name) {
            s.push_str(&format!("\n  {name} {}", timings.counted(name)));
        }
    }
    s.push_str(&format!("\n  samples     {}", output.samples));
    s.push_str(&format!("\n  bvh         {}", output.bvh));
    for (name, d) in &timings.phases {
        s.push_str(&format!("\n  {name:<11} {:.3} ms", d.as_secs_f64() * 1e3));
    }
    s.push_str(&format!(
        "\n  {:<11} {:.3} ms",
        "total",
        timings.total().as_secs_f64() * 1e3
    ));
    match glint::memory::peak_resident() {
        Some(b) => s.push_str(&format!(
            "\n  peak memory {} resident",
            glint::memory::human(b)
        )),
        None => s.push_str("\n  peak memory unknown on this system"),
    }
    s
}
