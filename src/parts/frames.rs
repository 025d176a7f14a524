//! An animation split over the tasks of an array: each task's share of the
//! frames (`cut::frame_share`) goes into one directory, which a stamp ties
//! to one render, and a requeued task keeps the frames it finished.

use std::path::Path;

use crate::Error;

/// The file in a frame directory that says which render its frames are of.
const FRAMES_STAMP: &str = ".glint-frames";

/// Before an animation's part renders into `dir`: the directory holds no
/// frames of another render. Writes the directory's stamp when it has none.
pub fn claim_frames(dir: &Path, digest: &str) -> Result<(), Error> {
    let stamp = dir.join(FRAMES_STAMP);
    let line = format!("render {digest}\n");
    let failed = |error: std::io::Error| Error::WriteFile {
        path: stamp.clone(),
        error,
    };
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
        Ok(found) => Err(Error::BadOutput {
            path: dir.to_path_buf(),
            reason: format!(
                "it holds frames of another render ({}; this one is {digest}: another scene, \
                 settings or glint version); give this render a directory of its own, or empty that one",
                found.trim()
            ),
        }),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            // Written to a temporary file and renamed: tasks starting
            // together write the same line, and none sees half of it.
            let mut tmp = tempfile::NamedTempFile::new_in(dir).map_err(failed)?;
            std::io::Write::write_all(&mut tmp, line.as_bytes()).map_err(failed)?;
            tmp.persist(&stamp).map_err(|e| failed(e.error))?;
            Ok(())
        }
        Err(e) => Err(Error::ReadImage {
            path: stamp.clone(),
            message: e.to_string(),
        }),
    }
}

/// Whether a frame is already there, whole: frames are written to a
/// temporary file and renamed, so one under its name decoded in full is done.
pub fn frame_done(path: &Path) -> bool {
    path.exists() && crate::images::framebuffer::open(path).is_ok()
}
