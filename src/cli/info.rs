use std::path::Path;
use std::process::ExitCode;

use glint::bvh::Bvh;
use glint::info::SceneInfo;
use glint::layout::GpuScene;
use glint::memory::MemoryNeed;

use glint::scene::Effects;

use super::{print_warnings, EffectArgs};

pub fn run(path: &Path, effects: &EffectArgs, size: [u32; 2]) -> anyhow::Result<ExitCode> {
    let scene = super::read_scene(path)?;
    print_warnings(&scene);
    // The tree the renderers build: over the scene as the camera sees it.
    let bvh = Bvh::build(&scene.in_view_space());
    let effects = Effects::resolve(&effects.settings().or(scene.settings));
    println!("scene       {}", path.display());
    println!(
        "{}",
        SceneInfo {
            scene: &scene,
            bvh: &bvh,
            effects,
        }
    );
    // What a render at this size needs beyond the scene and its BVH; the GPU
    // figure assumes a device that shares host memory (the worst case).
    let [width, height] = size;
    let cpu = MemoryNeed::image(width, height);
    let mut gpu = cpu.clone();
    let tile = glint::gpu::GpuRenderOptions::default().tile_size;
    let texels = glint::gpu::tile_texels(tile, width, height);
    gpu.add_gpu(&GpuScene::pack(&scene, &bvh), texels, true);
    gpu.add_gathered(glint::gpu::gathered_image_bytes(width, height, false));
    println!("memory      at {width}x{height}: CPU {cpu}");
    println!("            GPU {gpu}");
    match glint::memory::available() {
        Some(bytes) => println!("            available {}", glint::memory::human(bytes)),
        None => println!("            available: unknown on this system"),
    }
    Ok(ExitCode::SUCCESS)
}
