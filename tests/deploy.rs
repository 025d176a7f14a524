//! The shipped cluster recipes (deploy/) hold together: the Kubernetes
//! manifests parse as YAML and pass glint the index variable it reads, with
//! the same part count as the Job's completions and the stitch, on one
//! shared volume; the Slurm scripts are valid bash that ask glint for the
//! Slurm index and options it has. No real cluster runs here (CI's `.ci/slurm`
//! runs the Slurm scripts on a real single-node Slurm; Kubernetes has no
//! such stand-in here, docs/cluster.md says so).

mod common;

use std::collections::BTreeMap;

use yaml_rust2::{Yaml, YamlLoader};

fn read(rel: &str) -> String {
    std::fs::read_to_string(common::repo_path(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

fn docs(rel: &str) -> Vec<Yaml> {
    YamlLoader::load_from_str(&read(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

fn strings(y: &Yaml) -> Vec<String> {
    y.as_vec()
        .map(|v| {
            v.iter()
                .filter_map(|s| s.as_str().map(String::from))
                .collect()
        })
        .unwrap_or_default()
}

/// The value after `flag` in an argument list.
fn after(args: &[String], flag: &str) -> Option<String> {
    args.iter()
        .position(|a| a == flag)
        .and_then(|i| args.get(i + 1).cloned())
}

/// claimName of each volume by its name, and mountPath of each mount.
fn mounts(pod: &Yaml) -> BTreeMap<String, (String, String)> {
    let volumes: BTreeMap<String, String> = pod["volumes"]
        .as_vec()
        .expect("volumes")
        .iter()
        .filter_map(|v| {
            let claim = v["persistentVolumeClaim"]["claimName"].as_str()?;
            Some((v["name"].as_str()?.to_string(), claim.to_string()))
        })
        .collect();
    pod["containers"][0]["volumeMounts"]
        .as_vec()
        .expect("volumeMounts")
        .iter()
        .filter_map(|m| {
            let name = m["name"].as_str()?;
            let claim = volumes.get(name)?;
            Some((
                name.to_string(),
                (claim.clone(), m["mountPath"].as_str()?.to_string()),
            ))
        })
        .collect()
}

#[test]
fn kubernetes_manifests_have_the_shape_glint_needs() {
    let render = &docs("deploy/k8s/render-job.yaml")[0];
    let stitch = &docs("deploy/k8s/stitch-job.yaml")[0];
    let volume = &docs("deploy/k8s/parts-volume.yaml")[0];
    assert_eq!(render["kind"].as_str(), Some("Job"));
    assert_eq!(render["spec"]["completionMode"].as_str(), Some("Indexed"));
    let completions = render["spec"]["completions"].as_i64().expect("completions");
    let pod = &render["spec"]["template"]["spec"];
    let args = strings(&pod["containers"][0]["args"]);
    assert_eq!(args.first().map(String::as_str), Some("render"), "{args:?}");
    // Indexed Jobs set JOB_COMPLETION_INDEX, which `--part k8s/N` reads.
    let part = after(&args, "--part").expect("--part");
    let (source, n) = part.split_once('/').expect("I/N");
    let arg = glint::parts::PartArg::parse(&part).expect("glint takes it");
    assert_eq!(arg.from, glint::parts::IndexFrom::Kubernetes, "{part}");
    assert_eq!(source, "k8s");
    assert_eq!(
        n.parse::<i64>().ok(),
        Some(completions),
        "--part N against completions"
    );

    let stitch_pod = &stitch["spec"]["template"]["spec"];
    let stitch_args = strings(&stitch_pod["containers"][0]["args"]);
    assert_eq!(stitch_args.first().map(String::as_str), Some("stitch"));
    assert_eq!(after(&stitch_args, "--parts"), Some(n.to_string()));
    assert!(
        after(&stitch_args, "--wait").is_some(),
        "the stitch waits for the parts"
    );
    // Parts are written where the stitch looks: the same image path, on the
    // same claim, which the volume file defines.
    assert_eq!(args[2], stitch_args[1], "render OUT against stitch OUT");
    let claim = volume["metadata"]["name"].as_str().expect("claim name");
    assert_eq!(volume["kind"].as_str(), Some("PersistentVolumeClaim"));
    let out_dir = std::path::Path::new(&args[2])
        .parent()
        .expect("dir")
        .to_str()
        .expect("utf-8");
    for pod in [pod, stitch_pod] {
        let m = mounts(pod);
        assert!(
            m.values().any(|(c, path)| c == claim && path == out_dir),
            "{out_dir} is not the {claim} volume in {m:?}"
        );
        assert_eq!(pod["containers"][0]["image"].as_str(), Some("glint:latest"));
    }
    // The container image the manifests name is the one the Dockerfile builds.
    let dockerfile = read("deploy/k8s/Dockerfile");
    assert!(dockerfile.contains("-t glint ."), "{dockerfile}");
    assert!(
        dockerfile.contains("mesa-vulkan-drivers"),
        "lavapipe for CPU-only nodes"
    );
}

#[test]
fn slurm_scripts_are_valid_and_ask_for_what_glint_has() {
    let dir = common::repo_path("deploy/slurm");
    for name in [
        "render-part.sbatch",
        "render-frames.sbatch",
        "stitch.sbatch",
        "submit.sh",
    ] {
        let path = dir.join(name);
        let check = std::process::Command::new("bash")
            .arg("-n")
            .arg(&path)
            .output()
            .expect("bash");
        assert!(
            check.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&check.stderr)
        );
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(&path)
            .expect("script")
            .permissions()
            .mode();
        assert!(mode & 0o111 != 0, "{name} is not executable");
    }
    let part = read("deploy/slurm/render-part.sbatch");
    assert!(part.contains("--part \"slurm/$parts\""), "{part}");
    assert!(part.contains("#SBATCH --requeue"));
    let frames = read("deploy/slurm/render-frames.sbatch");
    assert!(
        frames.contains("--frames \"$frames\" --part \"slurm/$parts\""),
        "{frames}"
    );
    let stitch = read("deploy/slurm/stitch.sbatch");
    assert!(
        stitch.contains("stitch \"$1\" --parts \"$2\" --wait"),
        "{stitch}"
    );
    let submit = read("deploy/slurm/submit.sh");
    assert!(
        submit.contains("--dependency=\"afterok:$render\""),
        "{submit}"
    );
    // The options the scripts pass exist.
    let dir = common::cli::tmp();
    let help = common::cli::glint(&["render", "--help"], dir.path());
    let help = common::cli::stdout(&help);
    assert!(
        help.contains("--part <I/N>") && help.contains("--frames <N>"),
        "{help}"
    );
    let help = common::cli::stdout(&common::cli::glint(&["stitch", "--help"], dir.path()));
    assert!(
        help.contains("--parts <N>") && help.contains("--wait <SECONDS>"),
        "{help}"
    );
}
