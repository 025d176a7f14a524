use std::path::Path;
use std::process::ExitCode;

use glint::bvh::Bvh;
use glint::info::SceneInfo;

use glint::scene::Effects;

use super::{print_warnings, EffectArgs};

pub fn run(path: &Path, effects: &EffectArgs) -> anyhow::Result<ExitCode> {
    let scene = glint::scene::read_scene(path)?;
    print_warnings(&scene);
    let bvh = Bvh::build(&scene);
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
    Ok(ExitCode::SUCCESS)
}
