use std::path::Path;
use std::process::ExitCode;

use glint::bvh::Bvh;
use glint::info::SceneInfo;

use super::print_warnings;

pub fn run(path: &Path) -> anyhow::Result<ExitCode> {
    let scene = glint::scene::read_scene(path)?;
    print_warnings(&scene);
    let bvh = Bvh::build(&scene);
    println!("scene       {}", path.display());
    println!(
        "{}",
        SceneInfo {
            scene: &scene,
            bvh: &bvh
        }
    );
    Ok(ExitCode::SUCCESS)
}
