//! The scene's arrival: `-v` names the phases before the first ray
//! (`read`, `parse`, `normals` where the scene names model files), and
//! `glint bench load` reports them per input.

mod common;

use common::cli::*;

fn box_files(d: &std::path::Path) -> String {
    let mut obj = String::new();
    for k in 0..8 {
        let s = |bit: usize| if k >> bit & 1 == 1 { 1 } else { -1 };
        obj += &format!("v {} {} {}\n", s(0), s(1), s(2) - 5);
    }
    obj += "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";
    std::fs::write(d.join("box.obj"), &obj).unwrap();
    std::fs::write(
        d.join("box.scene"),
        "2\namb: 0 0 0\nmesh file: box.obj\nlight pos: 0 0 0 col: 1 1 1\n",
    )
    .unwrap();
    obj
}

#[test]
fn verbose_names_the_phases_before_the_first_ray() {
    let d = tmp();
    box_files(d.path());
    std::fs::write(
        d.path().join("plain.scene"),
        "1\namb: 0 0 0\nsphere pos: 0 0 -3 rad: 1 dif: 1 1 1 spe: 0 0 0 shi: 1\n",
    )
    .unwrap();
    let phases = |scene: &str| -> Vec<String> {
        let o = glint(
            &[
                "render",
                "-v",
                "--backend",
                "cpu",
                "--width",
                "32",
                "--height",
                "24",
                scene,
                "x.png",
            ],
            d.path(),
        );
        assert!(o.status.success(), "{}", stderr(&o));
        let err = stdout(&o) + &stderr(&o);
        let mut names: Vec<String> = Vec::new();
        for line in err
            .lines()
            .filter(|l| l.ends_with(" ms") && l.starts_with("  "))
        {
            let name = line
                .trim()
                .rsplitn(3, ' ')
                .nth(2)
                .unwrap_or("")
                .trim()
                .to_string();
            if !names.contains(&name) {
                names.push(name);
            }
        }
        names
    };
    let with_model = phases("box.scene");
    assert_eq!(
        with_model[..3],
        ["read", "parse", "normals"],
        "{with_model:?}"
    );
    assert!(with_model.contains(&"bvh".to_string()), "{with_model:?}");
    let plain = phases("plain.scene");
    assert_eq!(plain[0], "parse", "{plain:?}");
    assert!(
        !plain.contains(&"read".to_string()) && !plain.contains(&"normals".to_string()),
        "{plain:?}"
    );
}

/// `glint bench load`: a row per input, a model alone and a scene naming
/// it counting the same triangles and the model's bytes.
#[test]
fn bench_load_reports_each_inputs_phases() {
    let d = tmp();
    let obj = box_files(d.path());
    let o = glint(
        &["bench", "load", "--rounds", "2", "box.obj", "box.scene"],
        d.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let rows: Vec<&str> = out.lines().filter(|l| l.starts_with("| box.")).collect();
    assert_eq!(rows.len(), 2, "{out}");
    for row in &rows {
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        assert_eq!(cells[3], "12", "triangles: {row}");
        assert!(
            cells[11].parse::<f64>().is_ok_and(|r| r >= 0.0),
            "MB/s: {row}"
        );
    }
    let bytes = |row: &str| {
        row.split('|')
            .nth(2)
            .unwrap()
            .trim()
            .parse::<u64>()
            .unwrap()
    };
    assert_eq!(bytes(rows[0]), obj.len() as u64, "{out}");
    assert!(
        bytes(rows[1]) > bytes(rows[0]),
        "the scene counts its file and the model's"
    );
}
