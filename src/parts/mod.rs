//! One render split over many machines by the engines sites already run:
//! Slurm job arrays and Kubernetes Indexed Jobs hand each task an index,
//! `glint render --part I/N` (or `slurm/N`, `k8s/N`, `env/N`) renders that
//! share, and `glint stitch OUT --parts N` joins the shares bit for bit.
//!
//! - `crop`: `--crop` rectangles, a part as a full-size image with alpha,
//!   and stitching such images into one.
//! - `cut`: which pixels (or frames) each part holds, balanced by cost.
//! - `stamp`: what a part file records of itself, and its digest of the render.
//! - `frames`: an animation's frame directory shared by the tasks of an array.
//! - here: the index's source, part file names, the requeue check, and
//!   finding, waiting for and vetting the parts of a stitch.

pub mod crop;
pub mod cut;
pub mod frames;
pub mod stamp;

use std::fmt;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use crate::images::framebuffer::ImageFile;
use crate::Error;
use stamp::Stamp;

/// Most parts one render may have.
pub const MAX_PARTS: u32 = 1_000_000;

/// Where a task's index comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IndexFrom {
    /// Given in the argument (`--part 3/16`).
    Given(u32),
    /// Slurm job arrays: `SLURM_ARRAY_TASK_ID`.
    Slurm,
    /// Kubernetes Indexed Jobs: `JOB_COMPLETION_INDEX`.
    Kubernetes,
    /// Whichever of the two is set.
    Either,
}

const SLURM_VAR: &str = "SLURM_ARRAY_TASK_ID";
const K8S_VAR: &str = "JOB_COMPLETION_INDEX";

/// `--part I/N`, `slurm/N`, `k8s/N` or `env/N` as given.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PartArg {
    /// Where the index comes from.
    pub from: IndexFrom,
    /// How many parts the render is split into.
    pub count: u32,
}

/// Part `index` (0-based) of `count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PartOf {
    /// This part, counted from 0.
    pub index: u32,
    /// How many parts the render is split into.
    pub count: u32,
}

impl PartArg {
    /// Reads `I/N`, `slurm/N`, `k8s/N` or `env/N`; the message says what is expected.
    pub fn parse(s: &str) -> Result<PartArg, String> {
        let usage = || {
            format!(
                "expected I/N (part I of N, counted from 0, e.g. 3/16), slurm/N (I from \
                 {SLURM_VAR}), k8s/N (I from {K8S_VAR}) or env/N (either), with N from 1 to \
                 {MAX_PARTS}; found `{s}`"
            )
        };
        let (i, n) = s.split_once('/').ok_or_else(usage)?;
        let count: u32 = n.trim().parse().map_err(|_| usage())?;
        if !(1..=MAX_PARTS).contains(&count) {
            return Err(usage());
        }
        let from = match i.trim() {
            "slurm" => IndexFrom::Slurm,
            "k8s" | "kubernetes" => IndexFrom::Kubernetes,
            "env" => IndexFrom::Either,
            i => match i.parse::<u32>() {
                Ok(i) if i < count => IndexFrom::Given(i),
                Ok(i) => {
                    return Err(format!(
                        "part {i} of {count} does not exist: parts count from 0, so the last is {}",
                        count - 1
                    ))
                }
                Err(_) => return Err(usage()),
            },
        };
        Ok(PartArg { from, count })
    }

    /// The index, read from the environment (`var`) where the argument
    /// names a variable.
    pub fn resolve(&self, var: impl Fn(&str) -> Option<String>) -> Result<PartOf, Error> {
        let n = self.count;
        let read = |name: &str| -> Result<Option<u32>, Error> {
            let Some(v) = var(name) else { return Ok(None) };
            match v.trim().parse::<u32>() {
                Ok(i) if i < n => Ok(Some(i)),
                Ok(i) => Err(Error::InvalidOption(format!(
                    "{name} is {i}, but --part has {n} parts, 0 to {}: give the array the \
                     indices 0-{} (Slurm: --array=0-{}; Kubernetes: completions: {n})",
                    n - 1,
                    n - 1,
                    n - 1
                ))),
                Err(_) => Err(Error::InvalidOption(format!(
                    "{name} is `{v}`, not a task index (a whole number from 0)"
                ))),
            }
        };
        let missing = |names: &str, how: &str| {
            Error::InvalidOption(format!(
                "--part takes the part's index from {names}, which is not set: {how}, or give \
                 the index itself (--part I/{n})"
            ))
        };
        let index = match self.from {
            IndexFrom::Given(i) => i,
            IndexFrom::Slurm => read(SLURM_VAR)?.ok_or_else(|| {
                missing(
                    SLURM_VAR,
                    &format!(
                        "run it as a task of a job array (sbatch --array=0-{})",
                        n - 1
                    ),
                )
            })?,
            IndexFrom::Kubernetes => read(K8S_VAR)?.ok_or_else(|| {
                missing(
                    K8S_VAR,
                    "run it in a Kubernetes Job with completionMode: Indexed",
                )
            })?,
            IndexFrom::Either => match (read(SLURM_VAR)?, read(K8S_VAR)?) {
                (Some(a), Some(b)) if a != b => {
                    return Err(Error::InvalidOption(format!(
                        "--part env/{n}: {SLURM_VAR} is {a} but {K8S_VAR} is {b}; name the one \
                         to follow (--part slurm/{n} or --part k8s/{n})"
                    )))
                }
                (Some(i), _) | (None, Some(i)) => i,
                (None, None) => {
                    return Err(missing(
                        &format!("{SLURM_VAR} or {K8S_VAR}"),
                        "run it as a Slurm array task or a Kubernetes Indexed Job",
                    ))
                }
            },
        };
        Ok(PartOf { index, count: n })
    }
}

impl fmt::Display for PartOf {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "part {} of {}", self.index, self.count)
    }
}

/// The file part `index` of `count` of the image `out` is written to, beside
/// it: `table.png` -> `table.part03-of-16.png`. EXR for an EXR image (its
/// floats kept), else PNG (8-bit, what JPEG, PNG and PPM are made of).
pub fn part_path(out: &Path, index: u32, count: u32) -> PathBuf {
    let ext = match ImageFile::of(out) {
        Ok(ImageFile::Exr) => "exr",
        _ => "png",
    };
    let stem = out.file_stem().unwrap_or(out.as_os_str()).to_string_lossy();
    let digits = (count - 1).max(1).to_string().len();
    out.with_file_name(format!("{stem}.part{index:0digits$}-of-{count}.{ext}"))
}

/// What a re-run task finds where its part goes.
#[derive(Debug, PartialEq, Eq)]
pub enum Existing {
    /// Nothing there: render.
    None,
    /// This very part of this very render, whole: nothing to do.
    Done(Stamp),
    /// Something else (another render, an unreadable file): render over it.
    Other(String),
}

/// Whether the part at `path` is already done for the render `digest`: a
/// file there with this part's stamp that decodes in full. A half-written
/// part never has the name (parts are written to a temporary file and
/// renamed), so a requeued task redoes only what is missing.
pub fn existing(path: &Path, digest: &str, part: PartOf) -> Existing {
    if !path.exists() {
        return Existing::None;
    }
    let bytes = match crate::input::read_path(path, crate::input::Kind::Binary) {
        Ok(b) => b,
        Err(e) => return Existing::Other(format!("it cannot be read ({e})")),
    };
    match stamp::stamp_of(&bytes, path) {
        Ok(Some(s)) if s.render == digest && s.index == part.index && s.count == part.count => {
            match crate::images::framebuffer::decode_image(&bytes, path) {
                Ok(_) => Existing::Done(s),
                Err(e) => Existing::Other(format!("it does not decode ({e})")),
            }
        }
        Ok(Some(s)) if s.render != digest => Existing::Other(format!(
            "it is part {} of {} of another render ({}: another scene, settings or glint version)",
            s.index, s.count, s.render
        )),
        Ok(Some(s)) => Existing::Other(format!("it is part {} of {}", s.index, s.count)),
        Ok(None) => Existing::Other("it carries no part stamp".into()),
        Err(e) => Existing::Other(e.to_string()),
    }
}

/// Indices as a Slurm `--array` list: `3,7-9,12`.
pub fn index_list(indices: &[u32]) -> String {
    let mut out: Vec<String> = Vec::new();
    let mut i = 0;
    while i < indices.len() {
        let start = indices[i];
        let mut end = start;
        while i + 1 < indices.len() && indices[i + 1] == end + 1 {
            i += 1;
            end += 1;
        }
        out.push(if end > start {
            format!("{start}-{end}")
        } else {
            start.to_string()
        });
        i += 1;
    }
    out.join(",")
}

/// "part 3" or "parts 3,7-9".
pub fn parts_named(indices: &[u32]) -> String {
    match indices {
        [one] => format!("part {one}"),
        _ => format!("parts {}", index_list(indices)),
    }
}

/// The part files of `out` in `count` parts, once all are there: waits up
/// to `wait` for missing ones (checking every `poll`), calling `waiting`
/// with the indices still missing whenever that list changes. Missing
/// parts are an error naming their indices.
pub fn find_parts(
    out: &Path,
    count: u32,
    wait: Duration,
    poll: Duration,
    waiting: &mut dyn FnMut(&[u32]),
) -> Result<Vec<PathBuf>, Error> {
    let paths: Vec<PathBuf> = (0..count).map(|i| part_path(out, i, count)).collect();
    let deadline = Instant::now() + wait;
    let mut last: Option<Vec<u32>> = None;
    loop {
        let missing: Vec<u32> = (0..count)
            .filter(|&i| !paths[i as usize].exists())
            .collect();
        if missing.is_empty() {
            return Ok(paths);
        }
        if Instant::now() >= deadline {
            let list = index_list(&missing);
            let first = paths[missing[0] as usize].display();
            return Err(Error::Parts(format!(
                "{} of {count} missing ({first}{}){}; render them (Slurm: sbatch --array={list} \
                 with the same script re-runs just those) and stitch again",
                parts_named(&missing),
                if missing.len() > 1 { ", ..." } else { "" },
                if wait > Duration::ZERO {
                    format!(" after waiting {:.0} s", wait.as_secs_f64())
                } else {
                    String::new()
                }
            )));
        }
        if last.as_ref() != Some(&missing) {
            waiting(&missing);
            last = Some(missing);
        }
        std::thread::sleep(poll.min(deadline.saturating_duration_since(Instant::now())));
    }
}

/// What the stamps of a stitch's parts say, once they agree.
#[derive(Debug, Default)]
pub struct Vetted {
    /// Parts without a stamp (made by `--crop`).
    pub unstamped: usize,
    /// Each renderer and the indices of the parts it made, when more than
    /// one made them: equal within `compare`'s tolerances, not bit for bit.
    pub renderers: Vec<(String, Vec<u32>)>,
}

/// Checks that stamped parts belong to one render: the same digest; with
/// `count`, each file's stamp is the part its name says. Parts of another
/// render are an error naming them by index.
pub fn vet(paths: &[PathBuf], count: Option<u32>) -> Result<Vetted, Error> {
    let mut stamps = Vec::with_capacity(paths.len());
    let mut vetted = Vetted::default();
    for (i, path) in paths.iter().enumerate() {
        let s = stamp::read_stamp(path)?;
        if let (Some(n), Some(s)) = (count, &s) {
            if (s.index, s.count) != (i as u32, n) {
                return Err(Error::ReadImage {
                    path: path.clone(),
                    message: format!(
                        "it says it is part {} of {}, not part {i} of {n} as its name does; \
                         a part file keeps the name render --part gave it",
                        s.index, s.count
                    ),
                });
            }
        }
        if s.is_none() {
            vetted.unstamped += 1;
        }
        stamps.push(s);
    }
    // The render most parts belong to; the others are named.
    let mut renders: Vec<(&str, Vec<u32>)> = Vec::new();
    for s in stamps.iter().flatten() {
        match renders.iter_mut().find(|(d, _)| *d == s.render) {
            Some((_, v)) => v.push(s.index),
            None => renders.push((&s.render, vec![s.index])),
        }
    }
    if renders.len() > 1 {
        renders.sort_by_key(|(_, v)| std::cmp::Reverse(v.len()));
        let others: Vec<String> = renders[1..]
            .iter()
            .map(|(d, v)| format!("{} of render {d}", parts_named(v)))
            .collect();
        return Err(Error::Parts(format!(
            "the parts belong to different renders (another scene, settings or glint version): \
             most are of render {}, but {}; re-render those with the settings of the others \
             (a re-run task replaces a part of another render)",
            renders[0].0,
            others.join("; ")
        )));
    }
    for s in stamps.iter().flatten() {
        match vetted.renderers.iter_mut().find(|(r, _)| *r == s.renderer) {
            Some((_, v)) => v.push(s.index),
            None => vetted.renderers.push((s.renderer.clone(), vec![s.index])),
        }
    }
    if vetted.renderers.len() < 2 {
        vetted.renderers.clear();
    }
    Ok(vetted)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |name| {
            vars.iter()
                .find(|(k, _)| *k == name)
                .map(|(_, v)| v.to_string())
        }
    }

    proptest::proptest! {
        /// Any `--part` text and any variable's value: an index in range or
        /// an error, never a panic.
        #[test]
        fn any_part_argument_resolves_or_says_why(
            arg in proptest::prop_oneof!["\\PC{0,24}", "(slurm|k8s|env|[0-9]{1,8})/ ?[0-9]{1,8}"],
            value in proptest::prop_oneof!["\\PC{0,12}", " ?[0-9]{1,10}"],
        ) {
            if let Ok(p) = PartArg::parse(&arg) {
                let vars = [(SLURM_VAR, value.as_str()), (K8S_VAR, value.as_str())];
                for vars in [&vars[..1], &vars[1..], &[][..]] {
                    if let Ok(part) = p.resolve(env(vars)) {
                        proptest::prop_assert!(part.index < part.count && part.count == p.count);
                    }
                }
            }
        }
    }

    #[test]
    fn part_arguments_parse_and_read_their_index() {
        let given = PartArg::parse("3/16").expect("valid");
        assert_eq!(
            given.resolve(env(&[])).expect("given"),
            PartOf {
                index: 3,
                count: 16
            }
        );
        for bad in ["16/16", "3", "a/4", "1/0", "-1/4", "slurm/", "2/2000000"] {
            assert!(PartArg::parse(bad).is_err(), "{bad}");
        }
        let slurm = PartArg::parse("slurm/8").expect("valid");
        let k8s = PartArg::parse("k8s/8").expect("valid");
        let either = PartArg::parse("env/8").expect("valid");
        let s = [(SLURM_VAR, "5")];
        assert_eq!(slurm.resolve(env(&s)).expect("set").index, 5);
        assert_eq!(either.resolve(env(&s)).expect("set").index, 5);
        let e = slurm.resolve(env(&[])).expect_err("unset").to_string();
        assert!(e.contains(SLURM_VAR) && e.contains("--array=0-7"), "{e}");
        let e = k8s.resolve(env(&s)).expect_err("k8s unset").to_string();
        assert!(e.contains(K8S_VAR) && e.contains("Indexed"), "{e}");
        let k = [(K8S_VAR, "7")];
        assert_eq!(k8s.resolve(env(&k)).expect("set").index, 7);
        let e = k8s
            .resolve(env(&[(K8S_VAR, "8")]))
            .expect_err("range")
            .to_string();
        assert!(e.contains("is 8") && e.contains("0 to 7"), "{e}");
        let e = slurm
            .resolve(env(&[(SLURM_VAR, "x1")]))
            .expect_err("junk")
            .to_string();
        assert!(e.contains("`x1`"), "{e}");
        let both = [(SLURM_VAR, "1"), (K8S_VAR, "2")];
        assert!(either.resolve(env(&both)).is_err());
        assert!(either.resolve(env(&[])).is_err());
    }

    #[test]
    fn part_names_sort_and_keep_float_formats() {
        let p = |o: &str, i, n| part_path(Path::new(o), i, n).display().to_string();
        assert_eq!(p("out/table.png", 3, 16), "out/table.part03-of-16.png");
        assert_eq!(p("a.jpg", 0, 8), "a.part0-of-8.png");
        assert_eq!(p("a.exr", 99, 100), "a.part99-of-100.exr");
        assert_eq!(p("a.png", 0, 1), "a.part0-of-1.png");
        assert_eq!(index_list(&[0, 1, 2, 5, 7, 8]), "0-2,5,7-8");
    }

    #[test]
    fn missing_parts_are_named_by_index() {
        let dir = tempfile::tempdir().expect("temp dir");
        let out = dir.path().join("x.png");
        for i in [0, 2] {
            std::fs::write(part_path(&out, i, 5), b"").expect("write");
        }
        let mut heard = Vec::new();
        let e = find_parts(
            &out,
            5,
            Duration::from_millis(30),
            Duration::from_millis(10),
            &mut |m| heard.push(m.to_vec()),
        )
        .expect_err("missing")
        .to_string();
        assert!(e.contains("parts 1,3-4 of 5 missing"), "{e}");
        assert!(e.contains("--array=1,3-4"), "{e}");
        assert_eq!(heard, vec![vec![1, 3, 4]]);
    }
}
