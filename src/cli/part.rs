//! `glint render --part`: one task's share of a render spread over a Slurm
//! job array or a Kubernetes Indexed Job (`glint::parts`), requeue-safe: a
//! part (or frame) already done for the same render is kept, not redone.

use std::path::Path;

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
