//! `glint render --part`: one task's share of a render spread over a Slurm
//! job array or a Kubernetes Indexed Job (`glint::parts`), requeue-safe: a
//! part (or frame) already done for the same render is kept, not redone.

use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context as _;
use glint::parts::stamp::{render_digest, write_part, Stamp};
use glint::parts::{part_path, Existing, PartOf};
use glint::render::{RenderOptions, Renderer};
use glint::scene::Scene;

/// Everything beside the scene that decides a render's pixels, for its
/// digest. The backend is not in it: a part from a GPU and one from the CPU
/// reference belong to one render (stitch says when they are mixed).
pub(super) fn settings_text(options: &RenderOptions, scene: &Scene) -> String {
    format!(
        "{}x{} background {:?} precision {:?} methods {:?} effects {:?}",
        options.width,
        options.height,
        options.background.map(f32::to_bits),
        options.precision,
        options.methods,
        options.effects(scene)
    )
}

/// Resolves `--part` from the arguments and the environment.
pub(super) fn resolve(arg: &glint::parts::PartArg) -> Result<PartOf, glint::Error> {
    arg.resolve(|name| std::env::var(name).ok())
}

/// Renders part `part` of the image `out` into its part file, unless that
/// file already holds this part of this render.
pub(super) fn render(
    scene_path: &Path,
    scene: &Scene,
    options: &RenderOptions,
    part: PartOf,
    out: &Path,
    verbose: bool,
) -> anyhow::Result<ExitCode> {
    let path = part_path(out, part.index, part.count);
    let digest = render_digest(scene, &settings_text(options, scene));
    match glint::parts::existing(&path, &digest, part) {
        Existing::Done(s) => {
            println!(
                "{part} is already done: {} holds it ({}); nothing to do",
                path.display(),
                s.span
            );
            return Ok(ExitCode::SUCCESS);
        }
        Existing::Other(why) => eprintln!("note: replacing {}: {why}", path.display()),
        Existing::None => {}
    }
    let start = Instant::now();
    let renderer = Renderer::new(options)?;
    let (output, span) = renderer.render_part(scene, part.index, part.count, &|_, _| {})?;
    if let Some(note) = &output.note {
        eprintln!("note: {note}");
    }
    super::validation_verdict(output.validation_messages)?;
    let stamp = Stamp {
        render: digest,
        index: part.index,
        count: part.count,
        span,
        height: options.height,
        renderer: output.renderer.clone(),
    };
    write_part(&output.framebuffer(), &stamp, &path)
        .with_context(|| format!("rendering {}", scene_path.display()))?;
    println!(
        "wrote {} ({part} of {}x{}: {}, {} pixels; {}, {:.1} ms); join with `glint stitch {} --parts {}`",
        path.display(),
        options.width,
        options.height,
        span,
        span.pixels(),
        output.renderer,
        start.elapsed().as_secs_f64() * 1e3,
        out.display(),
        part.count
    );
    if verbose {
        println!("timings:\n{}", output.timings);
    }
    Ok(ExitCode::SUCCESS)
}

/// The file in a frame directory that says which render its frames are of.
const FRAMES_STAMP: &str = ".glint-frames";

/// Before an animation's part renders into `dir`: the directory holds no
/// frames of another render. Writes the directory's stamp when it has none.
pub(super) fn claim_frames(dir: &Path, digest: &str) -> anyhow::Result<()> {
    let stamp = dir.join(FRAMES_STAMP);
    let line = format!("render {digest}\n");
    // Read no more than a stamp can hold: whatever lies under that name.
    let read = std::fs::File::open(&stamp).and_then(|f| {
        let mut found = String::new();
        std::io::Read::read_to_string(
            &mut std::io::Read::take(f, 4 * line.len() as u64),
            &mut found,
        )
        .map(|_| found)
    });
    match read {
        Ok(found) if found == line => Ok(()),
        Ok(found) => anyhow::bail!(
            "{} holds frames of another render ({}; this one is {digest}: another scene, \
             settings or glint version); give this render a directory of its own, or empty that one",
            dir.display(),
            found.trim()
        ),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            // Written to a temporary file and renamed: tasks starting
            // together write the same line, and none sees half of it.
            let mut tmp = tempfile::NamedTempFile::new_in(dir)
                .with_context(|| format!("writing {}", stamp.display()))?;
            std::io::Write::write_all(&mut tmp, line.as_bytes())?;
            tmp.persist(&stamp)
                .with_context(|| format!("writing {}", stamp.display()))?;
            Ok(())
        }
        Err(e) => Err(e).with_context(|| format!("reading {}", stamp.display())),
    }
}

/// Whether a frame is already there, whole: frames are written to a
/// temporary file and renamed, so one under its name decoded in full is done.
pub(super) fn frame_done(path: &Path) -> bool {
    path.exists() && glint::framebuffer::open(path).is_ok()
}
