//! The docs name the code as it is: every `src/` path written in the README
//! or `docs/` exists, and `docs/how-it-works.md` maps every folder of `src/`.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn doc_files() -> Vec<PathBuf> {
    let mut files = vec![root().join("README.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root().join("docs"))
        .expect("docs/ exists")
        .map(|e| e.expect("a readable entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    files.extend(docs);
    files
}

/// Every `src/...` path in `text`: the run of path characters after `src/`,
/// without a sentence's closing punctuation.
fn src_paths(text: &str) -> BTreeSet<String> {
    let mut found = BTreeSet::new();
    let bytes = text.as_bytes();
    let mut at = 0;
    while let Some(i) = text[at..].find("src/") {
        let start = at + i;
        at = start + 4;
        // `glint-src/` or `/usr/src/` are not ours.
        if start > 0
            && (bytes[start - 1].is_ascii_alphanumeric() || b"-_/.".contains(&bytes[start - 1]))
        {
            continue;
        }
        let end = text[start..]
            .find(|c: char| !(c.is_ascii_alphanumeric() || "_/.-".contains(c)))
            .map_or(text.len(), |n| start + n);
        let path = text[start..end].trim_end_matches(['.', '-']);
        found.insert(path.to_string());
    }
    found
}

fn folders(dir: &Path, out: &mut Vec<String>) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("a readable folder")
        .map(|e| e.expect("a readable entry").path())
        .filter(|p| p.is_dir())
        .collect();
    entries.sort();
    for d in entries {
        let rel = d
            .strip_prefix(root())
            .expect("under the crate")
            .to_string_lossy();
        out.push(format!("{}/", rel.replace('\\', "/")));
        folders(&d, out);
    }
}

#[test]
fn every_src_path_in_the_docs_exists() {
    let mut missing = Vec::new();
    for file in doc_files() {
        let text = std::fs::read_to_string(&file).expect("a readable doc");
        for path in src_paths(&text) {
            if !root().join(&path).exists() {
                missing.push(format!("{}: {path}", file.display()));
            }
        }
    }
    assert!(
        missing.is_empty(),
        "paths the docs name but the tree lacks:\n{}",
        missing.join("\n")
    );
}

#[test]
fn how_it_works_maps_every_src_folder() {
    let text = std::fs::read_to_string(root().join("docs/how-it-works.md")).expect("readable");
    let named = src_paths(&text);
    let mut all = Vec::new();
    folders(&root().join("src"), &mut all);
    assert!(all.len() > 5, "src/ has its folders: {all:?}");
    let unmapped: Vec<&String> = all.iter().filter(|f| !named.contains(*f)).collect();
    assert!(
        unmapped.is_empty(),
        "folders docs/how-it-works.md does not map: {unmapped:?}"
    );
}

#[test]
fn the_path_reader_finds_paths_and_ignores_others() {
    let found =
        src_paths("see `src/cpu/trace/` and src/render.rs. Not /usr/src/linux or my-src/x.");
    let want: BTreeSet<String> = ["src/cpu/trace/", "src/render.rs"].map(String::from).into();
    assert_eq!(found, want);
}
