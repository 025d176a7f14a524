//! Render a scene given as a string into an 8-bit image in memory, on the
//! best device there is (a GPU, else the CPU reference), and read pixels.
//!
//! `cargo run --release --example render_string`

use glint::images::framebuffer::Image;
use glint::render::{Job, PixelFormat, Quiet, RenderOptions, Renderer, Sink};

/// One red sphere in front of the camera, lit from above and behind it.
const SCENE: &str = "\
2
amb: 0.1 0.1 0.1
sphere
pos: 0 0 -3
rad: 1
dif: 0.8 0.1 0.1
spe: 0.5 0.5 0.5
shi: 20
light
pos: 2 4 0
col: 1 1 1
";

fn main() -> Result<(), glint::Error> {
    let scene = glint::scene::parse_scene(SCENE.as_bytes(), "<string>")?;
    let options = RenderOptions {
        width: 160,
        height: 120,
        ..RenderOptions::default()
    };
    let renderer = Renderer::new(&options)?;
    if let Some(note) = renderer.note() {
        println!("note: {note}");
    }
    let done = renderer.run(&Job::new(&scene), &Sink::Memory(PixelFormat::Rgb8), &Quiet)?;
    let Image::Rgb8(image) = &done.output.image else {
        unreachable!("a memory sink of 8-bit pixels hands back 8-bit pixels");
    };
    let centre = image.get_pixel(80, 60).0;
    let corner = image.get_pixel(0, 0).0;
    println!(
        "{}x{} on {}: centre {centre:?} (the sphere), corner {corner:?} (the white background)",
        image.width(),
        image.height(),
        done.output.renderer
    );
    assert!(
        centre[0] > centre[1] && centre[0] > centre[2],
        "the sphere is red"
    );
    assert_eq!(corner, [255, 255, 255], "the background is white");
    Ok(())
}
