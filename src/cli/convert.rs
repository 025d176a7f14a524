use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context as _;
use glint::mesh::Format;

#[derive(clap::Args, Debug)]
pub struct ConvertArgs {
    /// A model (.obj, .ply, .off, .stl, .gltf, .glb) or a scene file
    /// (anything else).
    input: PathBuf,
    /// A classic scene (.scene or any other name), or .obj (with OUT.mtl
    /// beside it).
    out: PathBuf,
    /// A model's material where its file has none: diffuse colour.
    #[arg(long, value_name = "R,G,B", default_value = "0.7,0.7,0.7", value_parser = parse_rgb)]
    dif: [f64; 3],
    /// Specular colour, as --dif.
    #[arg(long, value_name = "R,G,B", default_value = "0.3,0.3,0.3", value_parser = parse_rgb)]
    spe: [f64; 3],
    /// Phong exponent, as --dif.
    #[arg(long, value_name = "S", default_value_t = 20.0)]
    shi: f64,
}

pub fn run(args: ConvertArgs) -> anyhow::Result<ExitCode> {
    let to_obj = Format::of(&args.out) == Some(Format::Obj);
    if !to_obj && Format::of(&args.out).is_some() {
        return Err(glint::Error::BadOutput {
            path: args.out.clone(),
            reason: "convert writes a classic scene or .obj; .ply, .off, .stl, .gltf and .glb \
                     are read only"
                .into(),
        }
        .into());
    }
    if args.shi < 0.0 || !args.shi.is_finite() {
        return Err(glint::Error::InvalidOption(format!(
            "--shi must be zero or more, found {}",
            args.shi
        ))
        .into());
    }
    glint::images::framebuffer::check_writable(&args.out)?;
    let scene = if Format::of(&args.input).is_some() {
        let material = glint::scene::Material {
            kd: glam::DVec3::from(args.dif),
            ks: glam::DVec3::from(args.spe),
            shininess: args.shi,
        };
        glint::scene::model_scene(&args.input, material)?
    } else {
        super::read_scene(&args.input)?
    };
    super::print_warnings(&scene);
    if to_obj {
        let mtl = args.out.with_extension("mtl");
        let mtl_name = mtl
            .file_name()
            .map_or("out.mtl".into(), |n| n.to_string_lossy().into_owned());
        let (obj_text, mtl_text, info) = glint::scene::write_obj(&scene, &mtl_name);
        write(&args.out, &obj_text)?;
        write(&mtl, &mtl_text)?;
        println!(
            "wrote {} ({} triangles) and {} ({} materials)",
            args.out.display(),
            info.triangles,
            mtl.display(),
            info.materials
        );
        if info.mixed_materials > 0 {
            eprintln!(
                "note: {} triangles have a material per corner; OBJ gives a face one, so each got its first corner's",
                info.mixed_materials
            );
        }
        if info.spheres_skipped + info.lights_skipped > 0 {
            eprintln!(
                "note: OBJ holds triangles only: {} spheres and {} lights were left out",
                info.spheres_skipped, info.lights_skipped
            );
        }
        return Ok(ExitCode::SUCCESS);
    }
    if Format::of(&args.input).is_some() {
        // The model's own coordinates, bit for bit, and the framing view
        // as a `camera` block: a starting point to edit.
        write(&args.out, &glint::scene::to_classic_text(&scene))?;
        println!(
            "wrote {} ({} triangles as the file placed them, the camera that frames them and a \
             light beside it)",
            args.out.display(),
            scene.triangles.len(),
        );
        eprintln!(
            "note: the view is a `camera` block, which classic tools do not read; `glint convert \
             {} OUT.scene` writes the scene in the classic camera's view",
            args.out.display()
        );
        return Ok(ExitCode::SUCCESS);
    }
    // The classic camera sees the scene as its camera block did.
    let mut classic = scene.in_view_space().into_owned();
    let fov = classic.fov();
    classic.camera = None;
    if fov != glint::camera::FOV_Y_DEGREES {
        classic.camera = Some(glint::scene::CameraSpec {
            fov,
            ..glint::scene::CameraSpec::CLASSIC
        });
        eprintln!(
            "note: the camera's field of view is {fov}°, not the classic 60°: it is kept as a \
             `camera` block, which classic tools do not read"
        );
    }
    write(&args.out, &glint::scene::to_classic_text(&classic))?;
    println!(
        "wrote {} ({} triangles, {} spheres, {} lights, in the classic camera's view)",
        args.out.display(),
        classic.triangles.len(),
        classic.spheres.len(),
        classic.lights.len()
    );
    Ok(ExitCode::SUCCESS)
}

/// R,G,B in f64, so that `--dif 0.3,...` is the scene file's 0.3.
fn parse_rgb(s: &str) -> Result<[f64; 3], String> {
    let v: Vec<Option<f64>> = s.split(',').map(|p| p.trim().parse().ok()).collect();
    match v.as_slice() {
        [Some(r), Some(g), Some(b)] if [r, g, b].iter().all(|c| (0.0..=1.0).contains(*c)) => {
            Ok([*r, *g, *b])
        }
        _ => Err(format!("expected R,G,B with each in [0, 1], found `{s}`")),
    }
}

fn write(path: &Path, text: &str) -> anyhow::Result<()> {
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}
