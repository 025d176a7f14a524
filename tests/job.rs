//! `Renderer::run`: a job's image is the same whichever sink takes it, a
//! job that cannot be done is refused before any work, and a part job
//! writes the stamped part file its requeue check recognises.

mod common;

use common::*;
use glint::images::framebuffer::{Image, ImageFile};
use glint::parts::crop::Crop;
use glint::parts::{existing, Existing, PartOf};
use glint::render::passes::StopAt;
use glint::render::{Backend, Frames, Job, PixelFormat, Quiet, RenderOptions, Renderer, Sink};

const SCENE: &str = "3\namb: 0.1 0.1 0.1\n\
    sphere pos: -0.5 0 -3 rad: 0.7 dif: 0.8 0.2 0.1 spe: 0.4 0.4 0.4 shi: 12\n\
    sphere pos: 0.6 0.1 -4 rad: 0.8 dif: 0.1 0.5 0.8 spe: 0.2 0.2 0.2 shi: 30\n\
    light pos: 2 3 0 col: 0.9 0.9 0.9\n";

fn renderer() -> Renderer {
    Renderer::new(&RenderOptions {
        width: 80,
        height: 60,
        backend: Backend::Cpu,
        ..RenderOptions::default()
    })
    .expect("the CPU reference")
}

#[test]
fn memory_and_file_sinks_hold_the_same_pixels() {
    let scene = scene_from(SCENE);
    let r = renderer();
    let dir = tempfile::tempdir().expect("temp dir");
    let job = Job::new(&scene);
    let float = r
        .run(&job, &Sink::Memory(PixelFormat::Float), &Quiet)
        .expect("renders");
    let bytes = r
        .run(&job, &Sink::Memory(PixelFormat::Rgb8), &Quiet)
        .expect("renders");
    assert!(float.written.is_none());
    let Image::Rgb8(rgb8) = &bytes.output.image else {
        panic!("an 8-bit memory sink hands back 8-bit pixels");
    };
    assert_eq!(&*float.output.image.to_rgb8(), rgb8);
    let path = dir.path().join("out.png");
    let done = r.run(&job, &Sink::file(&path), &Quiet).expect("writes");
    assert_eq!(done.written.as_deref(), Some(path.as_path()));
    assert!(done.output.timings.phase("encode").is_some());
    let read = glint::images::framebuffer::open(&path)
        .expect("readable")
        .to_rgb8();
    assert_eq!(&read, rgb8);
}

#[test]
fn jobs_that_cannot_be_done_are_refused_before_any_work() {
    let scene = scene_from(SCENE);
    let r = renderer();
    let dir = tempfile::tempdir().expect("temp dir");
    let crop = Crop::parse("0,0,10,10").expect("a crop");
    let stop = StopAt {
        target_rmse: Some(0.01),
        time_limit: None,
        adaptive: false,
    };
    let refused = |job: Job, sink: Sink, says: &str| {
        let e = r.run(&job, &sink, &Quiet).err().expect("refused");
        assert!(e.to_string().contains(says), "{e}");
        assert_eq!(e.exit_code(), 2, "{e}");
    };
    let memory = || Sink::Memory(PixelFormat::Float);
    refused(
        Job::new(&scene).crop(crop).until(stop),
        memory(),
        "a crop, a part or frames",
    );
    let frames = Frames {
        count: 4,
        range: None,
        part: None,
    };
    refused(Job::new(&scene).frames(frames), memory(), "Sink::Frames");
    let past = Frames {
        range: Some([2, 4]),
        ..frames
    };
    let to_dir = |name: &str| Sink::Frames {
        dir: dir.path().join(name),
        format: ImageFile::Png,
        encode: Default::default(),
    };
    refused(Job::new(&scene).frames(past), to_dir("f"), "last is 3");
    refused(
        Job::new(&scene).frames(frames),
        to_dir("f.png"),
        "image name",
    );
    let outside = Crop::parse("70,50,90,70").expect("a crop");
    refused(Job::new(&scene).crop(outside), memory(), "80x60");
    let part = PartOf { index: 2, count: 2 };
    refused(Job::new(&scene).part(part), memory(), "part 2 of 2");
    let part = PartOf { index: 0, count: 2 };
    refused(
        Job::new(&scene).part(part),
        Sink::Stdout(Default::default()),
        "name OUT",
    );
    refused(
        Job::new(&scene),
        Sink::file(dir.path().join("x.gif")),
        "x.gif",
    );
    refused(
        Job::new(&scene).crop(crop),
        Sink::file(dir.path().join("x.jpg")),
        "with --crop",
    );
    assert_eq!(std::fs::read_dir(dir.path()).expect("dir").count(), 0);
}

#[test]
fn a_part_job_writes_the_part_its_requeue_check_knows() {
    let scene = scene_from(SCENE);
    let options = RenderOptions {
        width: 80,
        height: 60,
        backend: Backend::Cpu,
        ..RenderOptions::default()
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("whole.exr");
    let part = PartOf { index: 1, count: 3 };
    let job = Job::new(&scene).part(part);
    let done = glint::render::run(&options, &job, &Sink::file(&out)).expect("a part");
    let written = done.written.expect("a part file");
    assert_eq!(written, glint::parts::part_path(&out, 1, 3));
    let span = done.span.expect("a span");
    assert!(span.pixels() > 0 && span.pixels() < 80 * 60);
    match existing(&written, &job.digest(&options), part) {
        Existing::Done(stamp) => assert_eq!(stamp.span, span),
        _ => panic!("the part file is not recognised as this part"),
    }
    let other = RenderOptions {
        background: [0.0; 3],
        ..options
    };
    assert!(matches!(
        existing(&written, &job.digest(&other), part),
        Existing::Other(_)
    ));
}

/// A frames job writes each frame of its range, numbered by the whole
/// animation's width; a still scene's frames are one image.
#[test]
fn a_frames_job_writes_its_range() {
    let scene = scene_from(SCENE);
    let dir = tempfile::tempdir().expect("temp dir");
    let frames = Frames {
        count: 1200,
        range: Some([7, 9]),
        part: None,
    };
    let sink = Sink::Frames {
        dir: dir.path().join("anim"),
        format: ImageFile::Png,
        encode: Default::default(),
    };
    let done = renderer()
        .run(&Job::new(&scene).frames(frames), &sink, &Quiet)
        .expect("frames");
    let f = done.frames.expect("a frames report");
    assert_eq!(
        (f.first, f.last, f.rendered, f.written, f.kept),
        (7, 9, 3, 3, 0)
    );
    let mut names: Vec<String> = std::fs::read_dir(dir.path().join("anim"))
        .expect("the frame directory")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["0007.png", "0008.png", "0009.png"]);
    let first =
        glint::images::framebuffer::open(&dir.path().join("anim/0007.png")).expect("a frame");
    let last =
        glint::images::framebuffer::open(&dir.path().join("anim/0009.png")).expect("a frame");
    assert_eq!(first.to_rgb8(), last.to_rgb8());
}
