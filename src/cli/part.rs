//! `glint render --part`: one task's share of a render spread over a Slurm
//! job array or a Kubernetes Indexed Job (`glint::parts`), requeue-safe: a
//! part (or frame) already done for the same render is kept, not redone.

use std::path::Path;

use anyhow::Context as _;
use glint::parts::{part_path, Existing, PartOf};
use glint::render::{Job, RenderOptions};

/// Resolves `--part` from the arguments and the environment.
pub(super) fn resolve(arg: &glint::parts::PartArg) -> Result<PartOf, glint::Error> {
    arg.resolve(|name| std::env::var(name).ok())
}

/// Whether the part file of `part` beside `out` already holds this part
/// of this render (said, and nothing to do); a file there that does not is
/// noted and rendered over.
pub(super) fn already_done(job: &Job, options: &RenderOptions, part: PartOf, out: &Path) -> bool {
    let path = part_path(out, part.index, part.count);
    match glint::parts::existing(&path, &job.digest(options), part) {
        Existing::Done(s) => {
            println!(
                "{part} is already done: {} holds it ({}); nothing to do",
                path.display(),
                s.span
            );
            true
        }
        Existing::Other(why) => {
            eprintln!("note: replacing {}: {why}", path.display());
            false
        }
        Existing::None => false,
    }
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
