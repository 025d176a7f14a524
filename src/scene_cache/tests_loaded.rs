//! The cache's loaded scenes: a hit is the scene a load makes, warnings
//! and all; a changed byte of the scene or of any file its models came
//! from is a miss; a damaged entry is ignored and made again.

use std::path::Path;

use super::loaded::{HIT, IGNORED, LOADERS, MISS};
use super::SceneCache;
use crate::mesh::report::Tolerance;
use crate::scene::Scene;

/// An OBJ grid of `n` x `n` quads (2n² triangles) using a material from
/// `grid.mtl`, one face without area (a warning), and a scene naming it
/// with a camera, settings, a sphere and a zero-length normal (another).
fn files(dir: &Path, n: usize) {
    let mut obj = String::from("mtllib grid.mtl\nmtllib absent.mtl\nusemtl red\n");
    for y in 0..=n {
        for x in 0..=n {
            obj += &format!(
                "v {} {} {}\n",
                x as f64 / n as f64,
                y as f64 / n as f64,
                ((x * y) % 7) as f64 * 0.01
            );
        }
    }
    let at = |x: usize, y: usize| y * (n + 1) + x + 1;
    for y in 0..n {
        for x in 0..n {
            obj += &format!(
                "f {} {} {} {}\n",
                at(x, y),
                at(x + 1, y),
                at(x + 1, y + 1),
                at(x, y + 1)
            );
        }
    }
    obj += "f 1 1 2\n";
    std::fs::write(dir.join("grid.obj"), obj).expect("write");
    std::fs::write(
        dir.join("grid.mtl"),
        "newmtl red\nKd 0.8 0.1 0.1\nKs 0.2 0.2 0.2\nNs 30\n",
    )
    .expect("write");
    std::fs::write(
        dir.join("grid.scene"),
        "4\namb: 0.1 0.1 0.1\nspp: 4\ncamera\neye: 0.5 0.5 3 look: 0.5 0.5 0 up: 0 1 0\n\
         mesh\nfile: grid.obj\n\
         sphere pos: 0 0 -3 rad: 0.5 dif: 1 1 1 spe: 0 0 0 shi: 1\n\
         triangle\n\
         pos: 0 0 -2 nor: 0 0 0 dif: 1 1 1 spe: 0 0 0 shi: 1\n\
         pos: 1 0 -2 nor: 0 0 1 dif: 1 1 1 spe: 0 0 0 shi: 1\n\
         pos: 0 1 -2 nor: 0 0 1 dif: 1 1 1 spe: 0 0 0 shi: 1\n\
         light pos: 2 2 2 col: 1 1 1 rad: 0.5\n",
    )
    .expect("write");
    settle();
}

/// Waits out the slack the cache allows file stamps (files changed just
/// before a load are not stored: they may have changed during it).
fn settle() {
    std::thread::sleep(std::time::Duration::from_millis(30));
}

/// `scene` without the load's times, which a hit does not have.
fn untimed(mut scene: Scene) -> Scene {
    for m in &mut scene.meshes {
        m.load_time = Default::default();
        m.read_time = Default::default();
        m.normals_time = Default::default();
    }
    scene
}

fn counted(c: &SceneCache, path: &Path) -> (Scene, [u64; 3]) {
    let (scene, t) = c.read_scene(path).expect("read");
    (scene, [t.counted(HIT), t.counted(MISS), t.counted(IGNORED)])
}

#[test]
fn a_hit_is_the_scene_a_load_makes() {
    let dir = tempfile::tempdir().expect("temp dir");
    files(dir.path(), 72);
    let path = dir.path().join("grid.scene");
    let c = SceneCache::new(dir.path().join("cache"), 1 << 30).keep_every_scene();
    let loaded = crate::scene::read_scene(&path).expect("load");
    assert!(loaded.triangles.len() > super::MIN_PRIMITIVES);
    assert!(!loaded.warnings.is_empty());
    let report = &loaded.meshes[0].report;
    assert!(report.counts.contains_key(&Tolerance::DegenerateFace));
    assert!(report.counts.contains_key(&Tolerance::MissingLibrary));
    // The model, the library it found and the one it did not.
    assert_eq!(
        loaded.meshes[0].files.len(),
        3,
        "{:?}",
        loaded.meshes[0].files
    );
    let (first, n) = counted(&c, &path);
    assert_eq!(n, [0, 1, 0]);
    let (second, n) = counted(&c, &path);
    assert_eq!(n, [1, 0, 0]);
    // Whole scenes are too long for a failure's message.
    assert!(untimed(first) == untimed(loaded.clone()));
    assert!(second == untimed(loaded));
}

#[test]
fn any_changed_input_is_a_miss() {
    let dir = tempfile::tempdir().expect("temp dir");
    files(dir.path(), 72);
    let path = dir.path().join("grid.scene");
    let c = SceneCache::new(dir.path().join("cache"), 1 << 30).keep_every_scene();
    counted(&c, &path);
    let edit = |name: &str, from: &str, to: &str| {
        let p = dir.path().join(name);
        let text = std::fs::read_to_string(&p).expect("read");
        assert!(text.contains(from), "{name}");
        std::fs::write(&p, text.replacen(from, to, 1)).expect("write");
    };
    let changes: [(&str, &str, &str, Option<&str>); 4] = [
        ("grid.scene", "amb: 0.1 0.1 0.1", "amb: 0.2 0.1 0.1", None),
        ("grid.obj", "f 1 1 2", "f 1 2 2", None),
        ("grid.mtl", "Kd 0.8", "Kd 0.7", None),
        ("absent.mtl", "", "", Some("newmtl blue\nKd 0 0 1\n")),
    ];
    for (name, from, to, create) in changes {
        match create {
            Some(text) => std::fs::write(dir.path().join(name), text).expect("write"),
            None => edit(name, from, to),
        }
        settle();
        let (scene, n) = counted(&c, &path);
        assert_eq!(n, [0, 1, 0], "{name} changed");
        let fresh = crate::scene::read_scene(&path).expect("load");
        assert!(untimed(scene) == untimed(fresh), "{name}");
        assert_eq!(counted(&c, &path).1, [1, 0, 0], "{name} stored again");
    }
}

#[test]
fn a_damaged_scene_entry_is_ignored_and_made_again() {
    let dir = tempfile::tempdir().expect("temp dir");
    files(dir.path(), 72);
    let path = dir.path().join("grid.scene");
    let c = SceneCache::new(dir.path().join("cache"), 1 << 30).keep_every_scene();
    let scene = untimed(counted(&c, &path).0);
    let entry = std::fs::read_dir(c.dir())
        .expect("dir")
        .map(|e| e.expect("entry").path())
        .find(|p| p.to_string_lossy().contains("scene-"))
        .expect("an entry");
    let good = std::fs::read(&entry).expect("read");
    for at in [60, good.len() / 2, good.len() - 3] {
        let mut bad = good.clone();
        bad[at] ^= 0x40;
        std::fs::write(&entry, &bad).expect("write");
        let (again, n) = counted(&c, &path);
        assert_eq!(n, [0, 1, 1], "a byte flipped at {at}");
        assert!(untimed(again) == scene, "a byte flipped at {at}");
    }
    std::fs::write(&entry, &good[..good.len() - 184]).expect("write");
    assert_eq!(counted(&c, &path).1, [0, 1, 1]);
    let (again, n) = counted(&c, &path);
    assert_eq!(n, [1, 0, 0]);
    assert!(again == scene);
}

#[test]
fn the_key_holds_every_loader() {
    let mut listed: Vec<String> = LOADERS
        .iter()
        .filter_map(|(p, _)| p.strip_prefix("../"))
        .map(String::from)
        .collect();
    listed.sort();
    let mut found = Vec::new();
    for dir in ["scene", "mesh"] {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src").join(dir);
        for e in std::fs::read_dir(root).expect("src") {
            let name = e.expect("entry").file_name().to_string_lossy().into_owned();
            found.push(format!("{dir}/{name}"));
        }
    }
    found.sort();
    let missing: Vec<_> = found.iter().filter(|f| !listed.contains(f)).collect();
    assert!(missing.is_empty(), "add to LOADERS: {missing:?}");
    for (i, t) in Tolerance::ALL.iter().enumerate() {
        assert_eq!(*t as usize, i);
    }
    assert_eq!(Tolerance::ALL.len(), Tolerance::TrailingData as usize + 1);
}

#[test]
fn a_scene_that_loads_fast_is_not_kept_but_its_load_is() {
    let dir = tempfile::tempdir().expect("temp dir");
    files(dir.path(), 72);
    let path = dir.path().join("grid.scene");
    let c = SceneCache::new(dir.path().join("cache"), 1 << 30);
    let (scene, t) = c.read_scene(&path).expect("read");
    // Loaded in far less than its 1.9 MB would take to read back at
    // 700 MB/s? Then not kept, and said; else kept.
    let kept = t.counted(super::loaded::SKIPPED) == 0;
    let entries = || std::fs::read_dir(c.dir()).map_or(0, |d| d.count());
    assert_eq!(entries(), usize::from(kept));
    let again = c.read_scene(&path).expect("read").0;
    assert!(untimed(again) == untimed(scene));
}
