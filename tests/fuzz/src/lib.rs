//! What each fuzz target runs: a reader of glint's input on arbitrary
//! bytes, then what the renderer does with a model that loads (triangles,
//! smooth normals, bounds), so a bad value that gets through is found where
//! it would be used. Files a model refers to are never read here.

use std::path::Path;

use glint::mesh::{self, Format, Refs};

/// A model of `format`: through the bounded stream reader, as `glint`
/// reads a pipe, then from the bytes in hand.
pub fn model(format: Format, data: &[u8]) {
    let path = Path::new("fuzz");
    if let Ok(m) = mesh::read(data, format, path) {
        use_mesh(&m);
    }
    if let Ok(m) = mesh::parse(data, format, path, Refs::None) {
        use_mesh(&m);
    }
}

fn use_mesh(m: &mesh::Mesh) {
    let tris = glint::scene::mesh::triangles(&m, None, |p| p, |n| n, |_| 0);
    assert_eq!(tris.len(), m.faces.len());
    for t in &tris {
        for v in &t.vertices {
            assert!(v.position.is_finite(), "a non-finite position got through");
        }
    }
    let _ = glint::scene::mesh::bounds(&m);
    let _ = m.report.summary();
}

/// A scene: the parser on the whole text, and the windowed reader.
pub fn scene(data: &[u8]) {
    let _ = glint::scene::parse_scene(data, "fuzz");
    let _ = glint::scene::parse_reader(data, Path::new("fuzz"));
}

/// What `cache_entry` damages: a real entry of each kind, its path and
/// body, and the scene they belong to.
struct CacheSetup {
    cache: glint::scene_cache::SceneCache,
    scene: std::path::PathBuf,
    entries: [(std::path::PathBuf, u32, u128, Vec<u8>); 2],
}

/// The scene cache's entries as glint reads them back: a real entry (a
/// scene's or a tree's: the first byte's low bit) changed as the rest of
/// the input says, five bytes a change (where, and the byte xored in; the
/// top bit of where cuts the body there instead), under a header that
/// vouches for the result, so the body's own checks are all that stand
/// between the bytes and a render. Inputs stay small; the entries are
/// made once, from 10,000 spheres (enough to be cached).
pub fn cache_entry(data: &[u8]) {
    static SETUP: std::sync::OnceLock<CacheSetup> = std::sync::OnceLock::new();
    let s = SETUP.get_or_init(cache_setup);
    let Some((&which, changes)) = data.split_first() else {
        return;
    };
    let (path, kind, key, template) = &s.entries[usize::from(which & 1)];
    let mut body = template.clone();
    for c in changes.chunks_exact(5) {
        let at = u32::from_le_bytes([c[0], c[1], c[2], c[3]]);
        if at & 0x8000_0000 != 0 {
            body.truncate((at & 0x7fff_ffff) as usize);
        } else if !body.is_empty() {
            let i = at as usize % body.len();
            body[i] ^= c[4];
        }
    }
    let mut entry = b"GLINTSC1".to_vec();
    entry.extend_from_slice(&kind.to_le_bytes());
    entry.extend_from_slice(&key.to_le_bytes());
    entry.extend_from_slice(&(body.len() as u64).to_le_bytes());
    entry.extend_from_slice(&xxhash_rust::xxh3::xxh3_64(&body).to_le_bytes());
    entry.extend_from_slice(&body);
    std::fs::write(path, entry).expect("write the entry");
    let (scene, _) = s
        .cache
        .read_scene(&s.scene)
        .expect("a damaged entry is a miss, not an error");
    cache_render(&s.cache, &scene);
}

fn cache_render(cache: &glint::scene_cache::SceneCache, scene: &glint::scene::Scene) {
    use glint::render::{Backend, RenderOptions, Renderer};
    let options = RenderOptions {
        width: 8,
        height: 8,
        backend: Backend::Cpu,
        scene_cache: Some(cache.clone()),
        ..RenderOptions::default()
    };
    let r = Renderer::new(&options).expect("the CPU reference");
    r.render(scene, &|_, _| {}).expect("a render");
}

fn cache_setup() -> CacheSetup {
    let dir = tempfile_dir();
    let mut text = String::from("10001\namb: 0.1 0.1 0.1\nlight pos: 0 0 0 col: 1 1 1\n");
    for i in 0..10_000 {
        let (x, y) = (i % 100, i / 100);
        text += &format!(
            "sphere pos: {} {} -5 rad: 0.004 dif: 1 1 1 spe: 0 0 0 shi: 1\n",
            f64::from(x) * 0.01 - 0.5,
            f64::from(y) * 0.01 - 0.5
        );
    }
    let scene_path = dir.join("grid.scene");
    std::fs::write(&scene_path, text).expect("write the scene");
    // Older than the cache's slack for files changed during a load.
    std::thread::sleep(std::time::Duration::from_millis(50));
    let cache = glint::scene_cache::SceneCache::new(dir.join("cache"), 1 << 30).keep_every_scene();
    let (scene, _) = cache.read_scene(&scene_path).expect("the scene");
    cache_render(&cache, &scene);
    let entry = |prefix: &str, kind: u32| {
        let path = std::fs::read_dir(cache.dir())
            .expect("the cache")
            .map(|e| e.expect("an entry").path())
            .find(|p| {
                p.file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with(prefix))
            })
            .expect("an entry of this kind");
        let name = path
            .file_stem()
            .expect("a name")
            .to_string_lossy()
            .into_owned();
        let key = u128::from_str_radix(&name[prefix.len()..], 16).expect("a key");
        let body = std::fs::read(&path).expect("read")[44..].to_vec();
        (path, kind, key, body)
    };
    CacheSetup {
        entries: [entry("scene-", 2), entry("bvh-", 1)],
        cache,
        scene: scene_path,
    }
}

/// A directory of its own for this process, left behind by design (the
/// fuzzer ends the process from anywhere).
fn tempfile_dir() -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("glint-fuzz-cache-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temp dir");
    dir
}
