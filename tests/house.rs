//! The house rules a reader relies on, checked on the source itself: no
//! circle in the module graph (a file that imports another never ends up
//! imported back by it, through any path), no source file past 800 lines
//! but the shader, and driver-specific decisions in the driver profile
//! alone. Test modules (`#[cfg(test)] mod tests`) are left out of the
//! graph: they may reach anywhere.

mod common;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("read src").flatten() {
        let path = entry.path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The module a file is: `src/gpu/render/mod.rs` -> ["gpu", "render"].
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).expect("under src");
    let mut parts: Vec<String> = rel
        .iter()
        .map(|p| p.to_string_lossy().trim_end_matches(".rs").to_string())
        .collect();
    if matches!(
        parts.last().map(String::as_str),
        Some("mod" | "lib" | "main")
    ) {
        parts.pop();
    }
    parts
}

/// The file's text without its test modules and comments.
fn code(text: &str) -> String {
    let mut out = String::new();
    let mut lines = text.lines().peekable();
    while let Some(line) = lines.next() {
        let t = line.trim_start();
        if t.starts_with("#[cfg(test)]") || t.starts_with("#[cfg(all(test") {
            // Skip the item that follows: up to its closing brace at the
            // same indentation (or the end of a one-line item).
            let Some(item) = lines.next() else { break };
            let indent = item.len() - item.trim_start().len();
            if item.trim_end().ends_with('{') {
                for l in lines.by_ref() {
                    if l.len() - l.trim_start().len() == indent && l.trim_start().starts_with('}') {
                        break;
                    }
                }
            }
            continue;
        }
        if t.starts_with("//") {
            continue;
        }
        out.push_str(line);
        out.push('\n');
    }
    out
}

/// `text` with every string literal's contents dropped (`"..."`, raw
/// strings too), so that a message such as "...; use a .png file" is not
/// read as a `use` item. Char literals are kept whole, lifetimes left be.
fn without_strings(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    let mut kept = 0;
    let ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    while i < b.len() {
        let raw = b[i] == b'r' && (i == 0 || !ident(b[i - 1])) && {
            let hashes = b[i + 1..].iter().take_while(|&&c| c == b'#').count();
            b.get(i + 1 + hashes) == Some(&b'"')
        };
        if b[i] == b'\'' {
            // A char literal ('x', '\n', '\u{..}') or a lifetime ('a).
            let close = if b.get(i + 1) == Some(&b'\\') {
                b[i + 2..]
                    .iter()
                    .position(|&c| c == b'\'')
                    .map(|p| i + 2 + p)
            } else {
                let len = text[i + 1..].chars().next().map_or(1, char::len_utf8);
                (b.get(i + 1 + len) == Some(&b'\'')).then_some(i + 1 + len)
            };
            i = close.map_or(i + 1, |c| c + 1);
        } else if raw || b[i] == b'"' {
            let hashes = if raw {
                b[i + 1..].iter().take_while(|&&c| c == b'#').count()
            } else {
                0
            };
            let open = if raw { i + 1 + hashes } else { i };
            out.push_str(&text[kept..open + 1]);
            let mut j = open + 1;
            loop {
                match b.get(j) {
                    None => break,
                    Some(b'\\') if !raw => j += 2,
                    Some(b'"')
                        if b[j + 1..]
                            .iter()
                            .take(hashes)
                            .filter(|&&c| c == b'#')
                            .count()
                            == hashes =>
                    {
                        break
                    }
                    _ => j += 1,
                }
            }
            kept = j.min(b.len());
            i = (j + 1 + hashes).min(b.len());
        } else {
            i += 1;
        }
    }
    out.push_str(&text[kept.min(text.len())..]);
    out
}

/// Paths that start with `crate::` or `super::` (in `use` trees too), as
/// module paths resolved against `module`.
fn references(module: &[String], is_mod_file: bool, text: &str) -> BTreeSet<Vec<String>> {
    let mut out = BTreeSet::new();
    let mut push = |path: Vec<String>| {
        out.insert(path);
    };
    // `use` items, with their brace trees flattened.
    for item in text.split(';') {
        let item = item.trim();
        let Some(u) = item
            .strip_prefix("use ")
            .or_else(|| item.strip_prefix("pub use "))
            .or_else(|| item.strip_prefix("pub(crate) use "))
        else {
            continue;
        };
        for path in expand(u.split_whitespace().collect::<String>().as_str()) {
            if let Some(p) = resolve(module, is_mod_file, &path) {
                push(p);
            }
        }
    }
    // Inline paths: `crate::a::b::c`, `super::x::y`.
    for start in ["crate::", "super::"] {
        let mut rest = text;
        while let Some(i) = rest.find(start) {
            let before = rest[..i].chars().last();
            let tail = &rest[i..];
            let end = tail
                .find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
                .unwrap_or(tail.len());
            if !before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
                let path: Vec<String> = tail[..end]
                    .split("::")
                    .filter(|s| !s.is_empty())
                    .map(str::to_string)
                    .collect();
                if let Some(p) = resolve(module, is_mod_file, &path) {
                    push(p);
                }
            }
            rest = &tail[end.max(1)..];
        }
    }
    out
}

/// `a::{b, c::{d, e}}` -> [a::b, a::c::d, a::c::e].
fn expand(tree: &str) -> Vec<Vec<String>> {
    let Some(open) = tree.find('{') else {
        return vec![tree.split("::").map(str::to_string).collect()];
    };
    let prefix: Vec<String> = tree[..open]
        .trim_end_matches("::")
        .split("::")
        .filter(|s| !s.is_empty())
        .map(str::to_string)
        .collect();
    let inner = &tree[open + 1..tree.rfind('}').unwrap_or(tree.len())];
    let mut parts = Vec::new();
    let (mut depth, mut from) = (0, 0);
    for (i, c) in inner.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                parts.push(&inner[from..i]);
                from = i + 1;
            }
            _ => {}
        }
    }
    parts.push(&inner[from..]);
    parts
        .into_iter()
        .filter(|p| !p.is_empty())
        .flat_map(expand)
        .map(|tail| prefix.iter().cloned().chain(tail).collect())
        .collect()
}

fn resolve(module: &[String], is_mod_file: bool, path: &[String]) -> Option<Vec<String>> {
    let first = path.first()?;
    let mut base: Vec<String> = match first.as_str() {
        "crate" => Vec::new(),
        "super" => {
            let mut m = module.to_vec();
            m.pop()?;
            m
        }
        "self" => module.to_vec(),
        // `use child::x` in a module that declares `mod child`: relative
        // to the module itself (only files that declare modules have them).
        name if is_mod_file
            && !name.is_empty()
            && name
                .chars()
                .all(|c| c.is_ascii_lowercase() || c == '_' || c.is_ascii_digit()) =>
        {
            let mut m = module.to_vec();
            m.push(name.to_string());
            return Some(m.into_iter().chain(path[1..].iter().cloned()).collect());
        }
        _ => return None,
    };
    let mut rest = &path[1..];
    while rest.first().is_some_and(|s| s == "super") {
        base.pop()?;
        rest = &rest[1..];
    }
    base.extend(rest.iter().cloned());
    Some(base)
}

/// The longest prefix of `path` that is a module with a file.
fn target<'a>(
    path: &[String],
    modules: &'a BTreeMap<Vec<String>, PathBuf>,
) -> Option<&'a Vec<String>> {
    (1..=path.len())
        .rev()
        .find_map(|n| modules.get_key_value(&path[..n]).map(|(k, _)| k))
}

struct Graph {
    modules: BTreeMap<Vec<String>, PathBuf>,
    edges: BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
}

fn graph() -> Graph {
    let src = common::repo_path("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    let modules: BTreeMap<Vec<String>, PathBuf> = files
        .iter()
        .filter(|f| !f.ends_with("main.rs"))
        .map(|f| (module_of(&src, f), f.clone()))
        .collect();
    let mut edges: BTreeMap<Vec<String>, BTreeSet<Vec<String>>> = BTreeMap::new();
    for (module, file) in &modules {
        let text = std::fs::read_to_string(file).expect("read source");
        let is_mod = file.ends_with("mod.rs") || file.ends_with("lib.rs");
        let mut to = BTreeSet::new();
        for path in references(module, is_mod, &without_strings(&code(&text))) {
            if let Some(t) = target(&path, &modules) {
                // A module's use of its own children counts (`pub use
                // child::X` included): a child that imports from its parent
                // closes a circle, as with any other module.
                if t != module {
                    to.insert(t.clone());
                }
            }
        }
        edges.insert(module.clone(), to);
    }
    Graph { modules, edges }
}

/// Strongly connected components of more than one module (Tarjan).
fn circles(g: &Graph) -> Vec<Vec<Vec<String>>> {
    struct T<'a> {
        g: &'a Graph,
        index: BTreeMap<&'a Vec<String>, usize>,
        low: BTreeMap<&'a Vec<String>, usize>,
        stack: Vec<&'a Vec<String>>,
        on: BTreeSet<&'a Vec<String>>,
        out: Vec<Vec<Vec<String>>>,
    }
    fn visit<'a>(t: &mut T<'a>, v: &'a Vec<String>) {
        let i = t.index.len();
        t.index.insert(v, i);
        t.low.insert(v, i);
        t.stack.push(v);
        t.on.insert(v);
        for w in &t.g.edges[v] {
            if !t.index.contains_key(w) {
                visit(t, w);
                let lw = t.low[w];
                let lv = t.low.get_mut(v).expect("visited");
                *lv = (*lv).min(lw);
            } else if t.on.contains(w) {
                let iw = t.index[w];
                let lv = t.low.get_mut(v).expect("visited");
                *lv = (*lv).min(iw);
            }
        }
        if t.low[v] == t.index[v] {
            let mut comp = Vec::new();
            while let Some(w) = t.stack.pop() {
                t.on.remove(w);
                comp.push(w.clone());
                if w == v {
                    break;
                }
            }
            if comp.len() > 1 {
                t.out.push(comp);
            }
        }
    }
    let mut t = T {
        g,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in g.modules.keys() {
        if !t.index.contains_key(v) {
            visit(&mut t, v);
        }
    }
    t.out
}

fn name(m: &[String]) -> String {
    if m.is_empty() {
        "crate".into()
    } else {
        m.join("::")
    }
}

#[test]
fn the_module_graph_has_no_circles() {
    let g = graph();
    let found = circles(&g);
    let mut report = String::new();
    for comp in &found {
        let set: BTreeSet<&Vec<String>> = comp.iter().collect();
        report += &format!(
            "circle of {}:\n",
            comp.iter().map(|m| name(m)).collect::<Vec<_>>().join(", ")
        );
        for m in comp {
            for w in g.edges[m].iter().filter(|w| set.contains(w)) {
                report += &format!("  {} -> {}\n", name(m), name(w));
            }
        }
    }
    assert!(found.is_empty(), "{report}");
}

/// The graph of `src/`'s top-level modules (a folder with everything in
/// it, or a file), each edge some file of one using some file of another.
fn top_level(g: &Graph) -> Graph {
    let top = |m: &Vec<String>| m.first().map(|t| vec![t.clone()]);
    let mut out = Graph {
        modules: BTreeMap::new(),
        edges: BTreeMap::new(),
    };
    for (m, file) in &g.modules {
        if let Some(t) = top(m) {
            out.modules.insert(t.clone(), file.clone());
            out.edges.entry(t).or_default();
        }
    }
    for (m, to) in &g.edges {
        let Some(from) = top(m) else { continue };
        for w in to {
            if let Some(w) = top(w).filter(|w| *w != from) {
                out.edges.entry(from.clone()).or_default().insert(w);
            }
        }
    }
    out
}

/// Folders import one way too: `scene` uses `mesh` (its `mesh` blocks) and
/// `mesh` nothing of `scene` (the material and number parsing both use sit
/// below them); `bvh` holds the lights-on-surfaces rule it builds.
#[test]
fn top_level_modules_import_one_way() {
    let g = top_level(&graph());
    assert!(g.modules.len() > 10, "{:?}", g.modules.keys());
    let found = circles(&g);
    let report: Vec<String> = found
        .iter()
        .map(|comp| comp.iter().map(|m| name(m)).collect::<Vec<_>>().join(", "))
        .collect();
    assert!(
        found.is_empty(),
        "circles among top-level modules: {report:?}"
    );
}

/// The checker finds what it is meant to find: a planted circle.
#[test]
fn the_circle_check_sees_a_planted_circle() {
    let m = |s: &str| -> Vec<String> { s.split("::").map(str::to_string).collect() };
    let mut g = Graph {
        modules: BTreeMap::new(),
        edges: BTreeMap::new(),
    };
    for (a, b) in [("a", "b"), ("b", "c"), ("c", "a"), ("c", "d")] {
        g.modules.insert(m(a), PathBuf::new());
        g.modules.insert(m(b), PathBuf::new());
        g.edges.entry(m(a)).or_default().insert(m(b));
        g.edges.entry(m(b)).or_default();
    }
    let found = circles(&g);
    assert_eq!(found.len(), 1);
    assert_eq!(found[0].len(), 3);
    let refs = references(
        &m("x::y"),
        false,
        "use super::z::{W, v::{Q}};\nlet a = crate::b::c(1);",
    );
    assert!(
        refs.contains(&m("x::z::W")) && refs.contains(&m("x::z::v::Q")),
        "{refs:?}"
    );
    assert!(refs.contains(&m("b::c")), "{refs:?}");
    let text = "use crate::a;\n#[cfg(test)]\nmod tests {\n    use crate::b;\n}\nfn f() {}\n";
    assert!(!code(text).contains("crate::b") && code(text).contains("fn f"));
}

/// Small files, each holding one idea: none past 800 lines, the shader's
/// pieces included.
#[test]
fn no_source_file_is_past_800_lines() {
    let mut files = Vec::new();
    sources(&common::repo_path("src"), &mut files);
    sources(&common::repo_path("tests"), &mut files);
    sources(&common::repo_path("benches"), &mut files);
    let mut shaders = vec![common::repo_path("shaders")];
    while let Some(dir) = shaders.pop() {
        for entry in std::fs::read_dir(&dir).expect("shaders/ is readable") {
            let path = entry.expect("an entry").path();
            if path.is_dir() {
                shaders.push(path);
            } else if path.extension().is_some_and(|e| e == "wgsl") {
                files.push(path);
            }
        }
    }
    assert!(files.iter().any(|f| f.ends_with("kernel.wgsl")));
    let long: Vec<String> = files
        .iter()
        .filter(|f| !f.components().any(|c| c.as_os_str() == "target"))
        .filter_map(|f| {
            let n = std::fs::read_to_string(f).ok()?.lines().count();
            (n > 800).then(|| format!("{} ({n} lines)", f.display()))
        })
        .collect();
    assert!(long.is_empty(), "split these: {long:?}");
}

/// A message that reads like code ("...; use crate::x") is not an import,
/// and char literals and raw strings do not throw the reading off.
#[test]
fn string_literals_are_not_read_as_imports() {
    let text = r##"const M: &str = "a; use crate::render::x"; let q = '"';
        let r = r#"use crate::gpu::y"#; fn f<'a>(s: &'a str) {} use crate::scene::Scene;"##;
    let plain = without_strings(text);
    assert!(
        !plain.contains("render") && !plain.contains("gpu"),
        "{plain}"
    );
    let refs = references(&["cli".to_string()], false, &plain);
    assert!(!refs.is_empty(), "the real import was missed");
    assert!(refs.iter().all(|p| p[0] == "scene"), "{refs:?}");
    let read_raw = references(&["cli".to_string()], false, text);
    assert!(read_raw.iter().any(|p| p[0] == "render"), "{read_raw:?}");
}

/// Driver knowledge in one room: no other file looks at a driver's name.
#[test]
fn only_the_driver_profile_names_drivers() {
    let src = common::repo_path("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    let mut offenders = Vec::new();
    for f in &files {
        if f.ends_with("gpu/driver.rs") {
            continue;
        }
        let text = code(&std::fs::read_to_string(f).expect("read"));
        for needle in [
            "\"llvmpipe",
            "\"Mesa",
            "\"NVIDIA",
            "\"AMD",
            "\"Intel",
            ".driver.contains",
            ".driver.starts_with",
            "driver.strip_prefix",
        ] {
            if text.contains(needle) {
                offenders.push(format!("{} has {needle}", f.display()));
            }
        }
    }
    assert!(offenders.is_empty(), "{offenders:?}");
}

/// Functions a reader can hold: none past 160 lines of source, but the
/// data tables (the check suite's list of cases).
#[test]
fn no_function_is_past_160_lines() {
    const TABLES: [&str; 1] = ["src/suites/check/suite.rs: cases"];
    let mut files = Vec::new();
    sources(&common::repo_path("src"), &mut files);
    let mut long = Vec::new();
    for file in &files {
        let text = std::fs::read_to_string(file).expect("read source");
        let lines: Vec<&str> = text.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            let Some((indent, name)) = fn_start(line) else {
                continue;
            };
            let end = lines[i + 1..]
                .iter()
                .position(|l| l.strip_prefix(indent) == Some("}"))
                .map_or(lines.len(), |k| i + 1 + k);
            let n = end - i + 1;
            let rel = file
                .strip_prefix(common::repo_path(""))
                .unwrap_or(file)
                .display()
                .to_string();
            let id = format!("{rel}: {name}");
            if n > 160 && !TABLES.contains(&id.as_str()) {
                long.push(format!("{id} ({n} lines)"));
            }
        }
    }
    assert!(long.is_empty(), "split these: {long:?}");
}

/// `fn name(` at the start of a line (after its indent and visibility),
/// with a body to follow: the indent and the name.
fn fn_start(line: &str) -> Option<(&str, &str)> {
    let rest = line.trim_start();
    let indent = &line[..line.len() - rest.len()];
    let mut words = rest.split_whitespace();
    let mut word = words.next()?;
    while matches!(word, "pub" | "const" | "unsafe" | "async" | "extern")
        || word.starts_with("pub(")
    {
        word = words.next()?;
    }
    if word != "fn" || line.trim_end().ends_with(';') {
        return None;
    }
    let name = words.next()?;
    let name = &name[..name.find(['(', '<']).unwrap_or(name.len())];
    Some((indent, name))
}

#[test]
fn the_function_reader_finds_starts_and_names() {
    assert_eq!(
        fn_start("    pub(super) fn run<'a>("),
        Some(("    ", "run"))
    );
    assert_eq!(fn_start("pub const fn f() -> u32 {"), Some(("", "f")));
    assert_eq!(fn_start("    fn g(&self) -> u32;"), None);
    assert_eq!(fn_start("    let f = 1;"), None);
}
