//! The scene cache from the command line: a second render reads the
//! scene and its tree back and draws the same image, renders at once
//! leave one whole entry, and the environment turns it off, moves it or
//! caps it.

mod common;

use std::path::Path;
use std::process::Command;

use common::cli::*;

/// A grid of 2·n² triangles as classic `triangle` blocks (text that
/// parses far slower than its entry reads back, so it is kept) and a
/// camera; then a pause, so the file is older than the cache's slack for
/// changes during a load.
fn grid_files(d: &Path, n: usize) {
    let mut text = format!("{}\namb: 0.1 0.1 0.1\n", 2 * n * n + 1);
    text += "camera\neye: 0.5 -0.8 1.5 look: 0.5 0.5 0 up: 0 0 1\n";
    let corner = |x: usize, y: usize| {
        let z = ((x * 7 + y * 3) % 5) as f64 * 0.01;
        format!(
            "pos: {:.15} {:.15} {z:.15} nor: 0 0 1 dif: 0.7 0.7 0.7 spe: 0.3 0.3 0.3 shi: 20\n",
            x as f64 / n as f64,
            y as f64 / n as f64
        )
    };
    for y in 0..n {
        for x in 0..n {
            for [a, b, c] in [
                [(x, y), (x + 1, y), (x + 1, y + 1)],
                [(x, y), (x + 1, y + 1), (x, y + 1)],
            ] {
                text += "triangle\n";
                for (cx, cy) in [a, b, c] {
                    text += &corner(cx, cy);
                }
            }
        }
    }
    text += "light pos: 2 -2 3 col: 0.9 0.9 0.9\n";
    std::fs::write(d.join("grid.scene"), text).unwrap();
    std::thread::sleep(std::time::Duration::from_millis(50));
}

const RENDER: [&str; 8] = [
    "render",
    "-v",
    "--backend",
    "cpu",
    "--width",
    "64",
    "--height",
    "48",
];

fn render(d: &Path, out: &str, env: &[(&str, &str)]) -> String {
    let mut args = RENDER.to_vec();
    args.extend(["grid.scene", out]);
    let o = glint_env(&args, d, env);
    assert!(o.status.success(), "{}", stderr(&o));
    stdout(&o) + &stderr(&o)
}

/// The entries in `dir`: scene and BVH files, and anything else.
fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .map(|r| {
            r.map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    names.sort();
    names
}

#[test]
fn a_second_render_reads_the_cache_and_draws_the_same_image() {
    let d = tmp();
    grid_files(d.path(), 72);
    let cache = d.path().join("cache");
    let env = [("GLINT_SCENE_CACHE", cache.to_str().unwrap())];
    let first = render(d.path(), "a.png", &env);
    assert!(first.contains("scene cache miss"), "{first}");
    assert!(first.contains("bvh cache miss"), "{first}");
    let names = entries(&cache);
    assert_eq!(names.len(), 2, "{names:?}");
    assert!(names[0].starts_with("bvh-") && names[1].starts_with("scene-"));
    let second = render(d.path(), "b.png", &env);
    assert!(second.contains("scene cache hit"), "{second}");
    assert!(second.contains("bvh cache hit"), "{second}");
    // Nothing was parsed or built: the cache's phases stand for them.
    for phase in ["parse", "normals", "bvh"] {
        let timed = |l: &str| {
            l.trim().strip_prefix(phase).is_some_and(|rest| {
                let ms = rest.trim().trim_end_matches(" ms");
                ms.len() < rest.trim().len() && ms.parse::<f64>().is_ok()
            })
        };
        assert!(!second.lines().any(timed), "{phase}: {second}");
    }
    assert_eq!(
        std::fs::read(d.path().join("a.png")).unwrap(),
        std::fs::read(d.path().join("b.png")).unwrap()
    );
    // Another view of the same scene: its tree is another, its scene not.
    let mut args = RENDER.to_vec();
    args.extend(["--eye", "0.5,-1,2", "grid.scene", "c.png"]);
    let o = glint_env(&args, d.path(), &env);
    let third = stdout(&o) + &stderr(&o);
    assert!(
        third.contains("scene cache hit") && third.contains("bvh cache miss"),
        "{third}"
    );
}

#[test]
fn renders_at_once_leave_one_whole_entry_each() {
    let d = tmp();
    grid_files(d.path(), 72);
    let cache = d.path().join("cache");
    let children: Vec<_> = (0..3)
        .map(|i| {
            let mut args = RENDER.to_vec();
            let out = format!("{i}.png");
            args.extend(["grid.scene", &out]);
            Command::new(env!("CARGO_BIN_EXE_glint"))
                .args(&args)
                .current_dir(d.path())
                .env("GLINT_SCENE_CACHE", &cache)
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for c in children {
        let o = c.wait_with_output().unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let image = |i: usize| std::fs::read(d.path().join(format!("{i}.png"))).unwrap();
    assert!(image(0) == image(1) && image(1) == image(2));
    let names = entries(&cache);
    assert_eq!(
        names.len(),
        2,
        "one scene and one tree, no temporary files: {names:?}"
    );
    let after = render(
        d.path(),
        "3.png",
        &[("GLINT_SCENE_CACHE", cache.to_str().unwrap())],
    );
    assert!(
        after.contains("scene cache hit") && after.contains("bvh cache hit"),
        "{after}"
    );
    assert!(image(3) == image(0));
}

#[test]
fn the_environment_places_caps_or_turns_off_the_cache() {
    let d = tmp();
    grid_files(d.path(), 72);
    let xdg = d.path().join("xdg");
    let run = |env: &[(&str, &str)]| {
        let mut args = RENDER.to_vec();
        args.extend(["grid.scene", "x.png"]);
        Command::new(env!("CARGO_BIN_EXE_glint"))
            .args(&args)
            .current_dir(d.path())
            .env_remove("GLINT_SCENE_CACHE")
            .env_remove("GLINT_SCENE_CACHE_SIZE")
            .env("XDG_CACHE_HOME", &xdg)
            .envs(env.iter().copied())
            .output()
            .unwrap()
    };
    // Off: nothing looked up, nothing written.
    let o = run(&[("GLINT_SCENE_CACHE", "off")]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        !(stdout(&o) + &stderr(&o)).contains("cache"),
        "{}",
        stdout(&o)
    );
    assert!(!xdg.exists());
    // By default: under the user's cache directory.
    assert!(run(&[]).status.success());
    assert_eq!(entries(&xdg.join("glint").join("scenes")).len(), 2);
    // A cap smaller than an entry: nothing kept, every run a miss, the
    // entries already there evicted by nothing they could not replace.
    let small = d.path().join("small");
    let env = [
        ("GLINT_SCENE_CACHE", small.to_str().unwrap()),
        ("GLINT_SCENE_CACHE_SIZE", "1K"),
    ];
    for _ in 0..2 {
        let o = run(&env);
        let said = stdout(&o) + &stderr(&o);
        assert!(
            said.contains("scene cache miss") && said.contains("bvh cache miss"),
            "{said}"
        );
    }
    assert!(entries(&small).is_empty(), "{:?}", entries(&small));
    // A size that is not one: said, with what to do.
    let o = run(&[("GLINT_SCENE_CACHE_SIZE", "lots")]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("GLINT_SCENE_CACHE_SIZE"),
        "{}",
        stderr(&o)
    );
}
