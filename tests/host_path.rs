//! The host path of a render (`encode`, the 8-bit pixels, pipelined
//! frames, the scene kept on the device): each shortcut gives the bytes the
//! plain path gives.
//!
//! - An 8-bit render (`PixelFormat::Rgb8`, what a PNG, JPEG or PPM asks
//!   for) equals the float render's `to_rgb8`, on every backend, on the
//!   classic scenes and the effect scenes.
//! - Every 8-bit file written from those pixels decodes to them (PNG and
//!   PPM exactly; JPEG as the same encode of the same pixels).
//! - Frames written by `--frames` (rendered while the last is encoded)
//!   equal single renders at each frame's time.
//! - A GPU animation whose triangles do not move uploads them once.
//! - On the GPU, pixels are packed on the device: 3 bytes a pixel read back
//!   for 8-bit files, the same pixels as the float render converted, and 12
//!   for floats, the texels' own bits; on the CPU
//!   they are made band by band in the render's threads, the same bytes.
//! - Tiles gathered on the device into one readback buffer give the bytes
//!   tiles read one by one give, and the host reads a whole image once.
//! - A device failing mid-animation leaves the finished frames whole.

mod common;

use std::path::Path;

use common::cli::{glint, tmp};
use common::*;
use glint::images::encode::EncodeOptions;
use glint::images::framebuffer::{Image, ImageFile};
use glint::render::{Backend, Job, PixelFormat, Quiet, RenderOptions, Renderer, Sink};
use glint::scene::Scene;
use glint::timing::{READBACK_BYTES, READBACK_READS, UPLOADED_BYTES};

const W: u32 = 96;
const H: u32 = 72;

fn backends() -> Vec<Backend> {
    let mut b = vec![Backend::Cpu];
    if gpu().is_some() {
        b.push(Backend::Gpu);
    }
    b
}

fn scenes() -> Vec<(String, Scene)> {
    let mut all = Vec::new();
    for name in ["soft_shadows", "antialias", "motion_blur", "reflect"] {
        let path = repo_path(&format!("scenes/effects/{name}.scene"));
        all.push((
            name.to_string(),
            glint::scene::read_scene(&path).expect("parses"),
        ));
    }
    match classic_dir() {
        Some(_) => {
            for name in CLASSIC {
                all.push((
                    name.to_string(),
                    classic_scene(name).expect("classic scene"),
                ));
            }
        }
        None => notice("SKIPPED: the classic scenes in host_path (no ../shared/scenes/classic)"),
    }
    all
}

fn renderer(width: u32, height: u32, backend: Backend, pixels: PixelFormat) -> Renderer {
    let options = RenderOptions {
        width,
        height,
        backend,
        pixels,
        ..Default::default()
    };
    Renderer::new(&options).expect("renderer")
}

fn render(scene: &Scene, backend: Backend, pixels: PixelFormat) -> Image {
    renderer(W, H, backend, pixels)
        .render(scene, &|_, _| {})
        .expect("renders")
        .image
}

#[test]
fn eight_bit_renders_equal_the_float_image_converted() {
    for backend in backends() {
        for (name, scene) in scenes() {
            let float = render(&scene, backend, PixelFormat::Float);
            let bytes = render(&scene, backend, PixelFormat::Rgb8);
            let Image::Float(fb) = &float else {
                panic!("{name}: a float render gave 8-bit pixels");
            };
            let Image::Rgb8(img) = &bytes else {
                panic!("{name}: an 8-bit render gave floats");
            };
            assert_eq!(img, &fb.to_rgb8(), "{name} on {backend:?}");
            for kind in [ImageFile::Png, ImageFile::Ppm] {
                let file = bytes
                    .encode(kind, &EncodeOptions::default())
                    .expect("encodes");
                let back = image::load_from_memory(&file).expect("decodes").to_rgb8();
                assert_eq!(&back, img, "{name} on {backend:?} as {kind:?}");
            }
            let jpeg = |i: &Image| i.encode(ImageFile::Jpeg, &EncodeOptions::default());
            assert_eq!(jpeg(&bytes), jpeg(&float), "{name} on {backend:?} as JPEG");
        }
    }
}

/// On the CPU an 8-bit render's pixels are made band by band in the render
/// threads (the float image is never whole): the same bytes as the float
/// render converted, for crops and parts (rows and pixels left out), on the
/// f32 packet path, and on the f64 pixel-by-pixel one.
#[test]
fn eight_bit_cpu_renders_convert_each_band_as_the_image_would() {
    #[derive(Debug)]
    enum Which {
        Whole,
        Crop(glint::parts::crop::Crop),
        Part(glint::parts::PartOf),
    }
    fn job<'a>(scene: &'a Scene, which: &Which) -> Job<'a> {
        match which {
            Which::Whole => Job::new(scene),
            Which::Crop(c) => Job::new(scene).crop(*c),
            Which::Part(p) => Job::new(scene).part(*p),
        }
    }
    let mut jobs = vec![
        Which::Whole,
        Which::Crop(glint::parts::crop::Crop::parse("13,7,61,50").expect("crop")),
    ];
    for index in 0..3 {
        jobs.push(Which::Part(glint::parts::PartOf { index, count: 3 }));
    }
    for (name, scene) in scenes().into_iter().take(5) {
        for precision in [glint::cpu::Precision::F32, glint::cpu::Precision::F64] {
            let options = RenderOptions {
                width: W,
                height: H,
                backend: Backend::Cpu,
                precision,
                ..Default::default()
            };
            let r = Renderer::new(&options).expect("renderer");
            for which in &jobs {
                let run = |pixels| {
                    r.run(&job(&scene, which), &Sink::Memory(pixels), &Quiet)
                        .expect("renders")
                };
                let (a, b) = (run(PixelFormat::Float), run(PixelFormat::Rgb8));
                assert!(
                    matches!(b.output.image, Image::Rgb8(_)),
                    "{name}: 8-bit pixels"
                );
                assert_eq!(
                    *b.output.image.to_rgb8(),
                    *a.output.image.to_rgb8(),
                    "{name}, {which:?}, {precision:?}"
                );
            }
        }
    }
}

/// A scene whose lights move: frames differ, the triangles stay.
fn moving_lights() -> String {
    let text = std::fs::read_to_string(repo_path("scenes/showcase.scene")).expect("showcase");
    // A light's block is `light`, `pos:`, `col:`; the velocity follows.
    let mut in_light = false;
    let mut out = Vec::new();
    for l in text.lines() {
        let word = l.split_whitespace().next().unwrap_or("");
        out.push(l.to_string());
        match word {
            "light" => in_light = true,
            "col:" if in_light => {
                out.push("vel: 1.5 0 -1".into());
                in_light = false;
            }
            "pos:" => {}
            _ => in_light = false,
        }
    }
    out.join("\n")
}

#[test]
fn pipelined_frames_equal_single_renders() {
    let dir = tmp();
    let scene_path = dir.path().join("moving.scene");
    std::fs::write(&scene_path, moving_lights()).expect("write scene");
    let scene = glint::scene::read_scene(&scene_path).expect("parses");
    assert!(scene.has_motion(), "the test scene's lights move");
    let (w, h) = ("64", "48");
    for (format, ext) in [("png", "png"), ("ppm", "ppm")] {
        let out = glint(
            &[
                "render",
                scene_path.to_str().expect("utf-8"),
                "frames",
                "--frames",
                "5",
                "--frame-format",
                format,
                "--backend",
                "cpu",
                "--width",
                w,
                "--height",
                h,
            ],
            dir.path(),
        );
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let renderer = renderer(64, 48, Backend::Cpu, PixelFormat::Float);
        let effects = renderer.options().effects(&scene);
        let mut distinct = std::collections::HashSet::new();
        for i in 0..5u32 {
            let want = renderer
                .render(&scene.at_time(effects.frame_time(i)), &|_, _| {})
                .expect("renders")
                .framebuffer()
                .to_rgb8();
            let file = dir.path().join(format!("frames/{i:03}.{ext}"));
            let got = read(&file);
            assert_eq!(got, want, "frame {i} as {format}");
            distinct.insert(got.into_raw());
        }
        assert!(distinct.len() > 1, "the frames should differ");
        let left: Vec<_> = std::fs::read_dir(dir.path().join("frames"))
            .expect("frames")
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().ends_with(".part"))
            .collect();
        assert!(left.is_empty(), "temporary files left: {left:?}");
        std::fs::remove_dir_all(dir.path().join("frames")).expect("clean");
    }
}

fn read(path: &Path) -> image::RgbImage {
    glint::images::framebuffer::read_image(path).expect("reads")
}

/// The second and later frames of a GPU animation upload what changed (the
/// frame's parameters, the moving lights), not the triangles again.
#[test]
fn an_animation_uploads_its_static_triangles_once() {
    if gpu().is_none() {
        return;
    }
    let scene = common::scene_from(&moving_lights());
    let renderer = renderer(48, 32, Backend::Gpu, PixelFormat::Float);
    let effects = renderer.options().effects(&scene);
    let uploaded: Vec<u64> = (0..4)
        .map(|i| {
            let out = renderer
                .render(&scene.at_time(effects.frame_time(i)), &|_, _| {})
                .expect("renders");
            out.timings.counted(UPLOADED_BYTES)
        })
        .collect();
    let triangles = scene.triangles.len() as u64 * 48; // 3 positions of 16 bytes at least
    assert!(
        uploaded[0] > triangles,
        "the first frame uploads the scene: {uploaded:?} bytes, triangles {triangles}"
    );
    for (i, &u) in uploaded.iter().enumerate().skip(1) {
        assert!(
            u > 0 && u < triangles,
            "frame {i} uploaded {u} bytes (all frames: {uploaded:?}); the triangles alone are about {triangles}"
        );
    }
}

/// On the GPU a render is packed on the device as its file needs: the host
/// reads 3 bytes a pixel for 8-bit pixels and 12 for floats (not the 16 of
/// a texel), the floats bit for bit the texels' own (`read_texels`), and
/// crops and parts are packed alike.
#[test]
fn gpu_renders_read_back_what_the_file_needs() {
    if gpu().is_none() {
        return;
    }
    let scene =
        glint::scene::read_scene(&repo_path("scenes/effects/soft_shadows.scene")).expect("parses");
    let float = renderer(W, H, Backend::Gpu, PixelFormat::Float);
    let bytes = renderer(W, H, Backend::Gpu, PixelFormat::Rgb8);
    let pixels = u64::from(W * H);
    let read = |out: &glint::render::RenderOutput| out.timings.counted(READBACK_BYTES);
    let a = float.render(&scene, &|_, _| {}).expect("renders");
    let b = bytes.render(&scene, &|_, _| {}).expect("renders");
    assert_eq!(read(&a), 12 * pixels);
    assert_eq!(read(&b), 3 * pixels);
    assert_eq!(*b.image.to_rgb8(), *a.image.to_rgb8());
    let mut options = RenderOptions {
        width: W,
        height: H,
        backend: Backend::Gpu,
        ..Default::default()
    };
    options.gpu.read_texels = true;
    let texels = Renderer::new(&options)
        .expect("renderer")
        .render(&scene, &|_, _| {})
        .expect("renders");
    assert_eq!(read(&texels), 16 * pixels);
    let bits = |out: &glint::render::RenderOutput| -> Vec<u32> {
        let fb = out.framebuffer();
        fb.pixels.iter().flatten().map(|v| v.to_bits()).collect()
    };
    assert!(
        bits(&a) == bits(&texels),
        "packed floats differ from the texels"
    );
    let crop = glint::parts::crop::Crop::parse("13,7,62,50").expect("crop");
    // A job's pixels come as its sink asks, whatever the renderer's options.
    let run = |r: &glint::render::Renderer, job: Job, pixels| {
        r.run(&job, &Sink::Memory(pixels), &Quiet).expect("renders")
    };
    let a = run(&float, Job::new(&scene).crop(crop), PixelFormat::Float);
    let b = run(&float, Job::new(&scene).crop(crop), PixelFormat::Rgb8);
    // 49 x 43: an odd count of pixels, so the last word is partly filled.
    assert_eq!(read(&b.output), 3 * 49 * 43);
    assert_eq!(read(&a.output), 12 * 49 * 43);
    assert_eq!(*b.output.image.to_rgb8(), *a.output.image.to_rgb8(), "crop");
    for index in 0..3 {
        let part = glint::parts::PartOf { index, count: 3 };
        let a = run(&bytes, Job::new(&scene).part(part), PixelFormat::Float);
        let b = run(&bytes, Job::new(&scene).part(part), PixelFormat::Rgb8);
        assert_eq!(a.span, b.span);
        assert_eq!(
            *b.output.image.to_rgb8(),
            *a.output.image.to_rgb8(),
            "part {index}"
        );
    }
}

/// Tiles gathered on the device (`GpuRenderOptions::gather`) give the
/// bytes that tiles read one by one give: many tiles, cut short at the
/// image's edges, that need passes and are redone resumable; whole images,
/// crops and parts; 8-bit pixels and floats (bit for bit). A gathered whole
/// image is read by the host once.
#[test]
fn tiles_gathered_on_the_device_equal_tiles_read_one_by_one() {
    if gpu().is_none() {
        return;
    }
    let scene =
        glint::scene::read_scene(&repo_path("scenes/effects/soft_shadows.scene")).expect("parses");
    let make = |gather: bool| {
        let mut options = RenderOptions {
            width: W,
            height: H,
            backend: Backend::Gpu,
            tile: Some(16),
            // Small enough that soft shadows' pixels need passes.
            pass_budget: Some(48),
            ..Default::default()
        };
        options.gpu.gather = gather;
        Renderer::new(&options).expect("renderer")
    };
    let (gathered, one_by_one) = (make(true), make(false));
    let tiles = u64::from(W.div_ceil(16) * H.div_ceil(16));
    let crop = glint::parts::crop::Crop::parse("13,7,62,50").expect("crop");
    let part = glint::parts::PartOf { index: 1, count: 3 };
    let bits = |image: &Image| -> Vec<u32> {
        match image {
            Image::Float(fb) => fb.pixels.iter().flatten().map(|v| v.to_bits()).collect(),
            Image::Rgb8(img) => img.as_raw().iter().map(|&v| u32::from(v)).collect(),
        }
    };
    for pixels in [PixelFormat::Rgb8, PixelFormat::Float] {
        let jobs = [
            ("whole", Job::new(&scene)),
            ("crop", Job::new(&scene).crop(crop)),
            ("part", Job::new(&scene).part(part)),
        ];
        for (what, job) in jobs {
            let run = |r: &Renderer| r.run(&job, &Sink::Memory(pixels), &Quiet).expect("renders");
            let (a, b) = (run(&gathered), run(&one_by_one));
            let at = format!("{what}, {pixels:?}");
            assert!(bits(&a.output.image) == bits(&b.output.image), "{at}");
            let count = |out: &glint::render::RenderOutput, name| out.timings.counted(name);
            assert_eq!(
                count(&a.output, READBACK_BYTES),
                count(&b.output, READBACK_BYTES),
                "{at}"
            );
            if what == "whole" {
                assert!(count(&a.output, "passes") > tiles, "no tile needed passes");
                assert_eq!(count(&a.output, READBACK_READS), 1, "{at}");
                assert_eq!(count(&b.output, READBACK_READS), tiles, "{at}");
            }
        }
    }
}

/// A device that fails mid-animation (`GLINT_FAULT`, a test-only fault at
/// the Nth pass submission) ends the run with exit 1 and a message naming
/// the Vulkan call; the frames finished before it are written whole and
/// equal a clean run's, no partial file is left; a single render that
/// fails writes nothing, also where the fault falls among a tile's queued
/// passes.
#[test]
fn a_device_failing_mid_animation_keeps_the_finished_frames() {
    if gpu().is_none() {
        return;
    }
    let dir = tmp();
    let scene_path = dir.path().join("moving.scene");
    std::fs::write(&scene_path, moving_lights()).expect("write scene");
    let scene = scene_path.to_str().expect("utf-8");
    let run = |out: &str, fault: Option<&str>| {
        let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_glint"));
        c.args(["render", scene, out, "--backend", "gpu", "--width", "64"])
            .args(["--height", "48", "--frames", "6", "--frame-format", "png"])
            .current_dir(dir.path());
        if let Some(f) = fault {
            c.env("GLINT_FAULT", f);
        }
        c.output().expect("run glint")
    };
    let clean = run("clean", None);
    assert!(
        clean.status.success(),
        "{}",
        String::from_utf8_lossy(&clean.stderr)
    );
    for (fault, says) in [
        ("lost@4", "vkQueueSubmit returned VK_ERROR_DEVICE_LOST"),
        (
            "oom@4",
            "vkQueueSubmit failed: A device memory allocation has failed",
        ),
    ] {
        let out = format!("faulty-{}", &fault[..fault.len() - 2]);
        let o = run(&out, Some(fault));
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{fault}: {stderr}");
        assert!(stderr.contains(says), "{fault}: {stderr}");
        let mut names: Vec<String> = std::fs::read_dir(dir.path().join(&out))
            .expect("frame directory")
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert!(
            names.iter().all(|n| !n.ends_with(".part")),
            "{fault}: a partial file was left: {names:?}"
        );
        let want: Vec<String> = (0..names.len()).map(|i| format!("{i:03}.png")).collect();
        assert_eq!(
            names, want,
            "{fault}: the frames written are not the first ones"
        );
        assert!(
            (1..6).contains(&names.len()),
            "{fault}: {} frames written before the fault at the 4th submission",
            names.len()
        );
        for n in &names {
            assert_eq!(
                read(&dir.path().join(&out).join(n)),
                read(&dir.path().join("clean").join(n)),
                "{fault}: {n}"
            );
        }
    }
    let single = std::process::Command::new(env!("CARGO_BIN_EXE_glint"))
        .args([
            "render",
            scene,
            "one.png",
            "--backend",
            "gpu",
            "--width",
            "64",
            "--height",
            "48",
        ])
        .env("GLINT_FAULT", "lost@1")
        .current_dir(dir.path())
        .output()
        .expect("run glint");
    assert_eq!(
        single.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&single.stderr)
    );
    assert!(!dir.path().join("one.png").exists());
    // A fault among a tile's queued passes: its one-pass try and resumable
    // redo are submissions 1 and 2, then a chain of two, whose second (the
    // 4th) fails with the first in flight. The same clean end.
    let effects = repo_path("scenes/effects/soft_shadows.scene");
    let chained = std::process::Command::new(env!("CARGO_BIN_EXE_glint"))
        .arg("render")
        .arg(&effects)
        .args(["chained.png", "--backend", "gpu", "--width", "64"])
        .args(["--height", "48", "--pass-budget", "8"])
        .env("GLINT_FAULT", "oom@4")
        .current_dir(dir.path())
        .output()
        .expect("run glint");
    let stderr = String::from_utf8_lossy(&chained.stderr);
    assert_eq!(chained.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("vkQueueSubmit failed"), "{stderr}");
    assert!(!dir.path().join("chained.png").exists());
}
