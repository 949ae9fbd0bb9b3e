//! End-to-end tests of scenes: every shipped scene loads and its BVHs
//! validate, renders are real PNGs, malformed meshes give one-line errors.

use crate::common::*;

use std::path::PathBuf;
use std::process::Output;

#[test]
fn every_scene_loads_and_its_bvhs_validate() {
    // The large DRS scenes are listed (and checked at the paper's scale) by
    // `every_drs_scene_is_at_the_papers_scale`.
    let small = [
        "conference",
        "trex",
        "fern",
        "saloon",
        "fairy",
        "layers",
        "sphere",
        "bmw",
        "ferrari",
        "truck",
    ];
    let mut args = vec!["list", "scenes"];
    args.extend(small);
    args.extend(["--format", "json"]);
    let o = rtsim(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let rows = j["rows"].as_array().unwrap();
    let get = |n: &str, metric: &str| {
        rows.iter()
            .find(|r| r["name"] == n && r["metric"] == metric)
            .map(|r| r["value"].as_f64().unwrap())
    };
    for n in ["conference", "fern", "saloon", "fairy", "layers", "sphere"] {
        assert!(get(n, "triangles").unwrap() > 1000.0, "{n}");
    }
    // The multi-hit truck: 128 s + 2 s per drum triangles at s = 256 sides.
    let truck = get("truck", "triangles").unwrap();
    assert!((150_000.0..300_000.0).contains(&truck), "truck: {truck}");
    for n in ["fern", "saloon", "fairy", "conference"] {
        let r = get(n, "triangles_vs_paper").unwrap();
        assert!((0.75..=1.25).contains(&r), "{n}: {r} of the paper's count");
    }
    assert_eq!(get("trex", "triangles"), Some(69_453.0));
    // The MBVH paper's cars at its counts (simplified from the BMW M6).
    for n in ["bmw", "ferrari"] {
        let r = get(n, "triangles_vs_paper").unwrap();
        assert!((0.95..=1.05).contains(&r), "{n}: {r} of the paper's count");
    }
    assert!(rows
        .iter()
        .any(|r| r["metric"] == "bvh2_sah_cost" && r["value"].as_f64().unwrap() > 1.0));
    let e = err(&rtsim(&["list", "scenes", "atlantis"]));
    assert!(e.contains("atlantis") && e.contains("one of"), "{e}");
    let e = err(&rtsim(&["list", "machines", "dragon"]));
    assert!(e.contains("takes no names"), "{e}");
}

#[test]
fn the_drs_scenes_but_the_courtyard_are_at_the_papers_scale() {
    drs_scenes_at_the_papers_scale(&["crown", "bentley", "dragon"]);
}

#[test]
#[ignore = "builds the 7.8M-triangle courtyard: cargo test --workspace -- --ignored"]
fn the_drs_courtyard_is_at_the_papers_scale() {
    drs_scenes_at_the_papers_scale(&["sanmiguel"]);
}

/// `rtsim list scenes` gives each of `names` within 25% of the paper's
/// triangle count.
fn drs_scenes_at_the_papers_scale(names: &[&str]) {
    let mut args = vec!["list", "scenes"];
    args.extend(names);
    args.extend(["--format", "json"]);
    let o = rtsim(&args);
    let j: serde_json::Value = serde_json::from_str(&ok(&o)).unwrap();
    let rows = j["rows"].as_array().unwrap();
    for &n in names {
        let r = rows
            .iter()
            .find(|r| r["name"] == n && r["metric"] == "triangles_vs_paper")
            .map(|r| r["value"].as_f64().unwrap())
            .unwrap();
        assert!((0.75..=1.25).contains(&r), "{n}: {r} of the paper's count");
    }
}

fn png_size(p: &PathBuf) -> (u32, u32) {
    let b = std::fs::read(p).unwrap();
    assert_eq!(&b[..8], &[0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a]);
    (
        u32::from_be_bytes(b[16..20].try_into().unwrap()),
        u32::from_be_bytes(b[20..24].try_into().unwrap()),
    )
}

#[test]
fn render_writes_png_in_every_shading() {
    for shade in ["normals", "depth", "hits"] {
        let out = tmp(&format!("sphere-{shade}.png"));
        let o = rtsim(&[
            "render",
            "--scene",
            "sphere",
            "--shade",
            shade,
            "--width",
            "64",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(png_size(&out), (64, 64));
    }
    for scene in ["dragon", "bentley"] {
        let out = tmp(&format!("{scene}.png"));
        let o = rtsim(&[
            "render",
            "--scene",
            scene,
            "--width",
            "48",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(png_size(&out).0, 48);
    }
}

#[test]
fn a_mesh_file_is_a_scene() {
    let f = tmp("tri.obj");
    std::fs::write(&f, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let out = tmp("tri.png");
    let o = rtsim(&[
        "render",
        "--scene",
        f.to_str().unwrap(),
        "--width",
        "32",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

fn one_line_error(o: &Output) -> String {
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8(o.stderr.clone()).unwrap();
    assert_eq!(e.trim_end().lines().count(), 1, "one line: {e}");
    assert!(!e.contains("panicked"));
    e
}

#[test]
fn malformed_obj_and_ply_are_one_line_errors() {
    let out = tmp("never.png");
    let f = tmp("bad.obj");
    std::fs::write(&f, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n").unwrap();
    let e = one_line_error(&rtsim(&[
        "render",
        "--scene",
        f.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    assert!(
        e.contains("bad.obj: line 4") && e.contains("out of range"),
        "{e}"
    );
    let f = tmp("nan.obj");
    std::fs::write(&f, "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let e = one_line_error(&rtsim(&[
        "render",
        "--scene",
        f.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    assert!(e.contains("nan.obj: line 2"), "{e}");
    let f = tmp("bad.ply");
    let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
    b.extend(std::iter::repeat_n(0u8, 20)); // truncated: 36 bytes of vertices expected
    std::fs::write(&f, &b).unwrap();
    let e = one_line_error(&rtsim(&[
        "render",
        "--scene",
        f.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    assert!(
        e.contains("bad.ply: byte") && e.contains("truncated"),
        "{e}"
    );
    let f = tmp("empty.obj");
    std::fs::write(&f, "# nothing\n").unwrap();
    let e = one_line_error(&rtsim(&[
        "render",
        "--scene",
        f.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    assert!(e.contains("empty scene"), "{e}");
    let e = one_line_error(&rtsim(&[
        "render",
        "--scene",
        "atlantis",
        "--out",
        out.to_str().unwrap(),
    ]));
    assert!(e.contains("atlantis"), "{e}");
    assert!(!out.exists(), "nothing half-written");
}

/// `rtsim` run from a scratch folder with `RTSIM_DATA` unset (no data folder
/// beside the working directory): it reads only what the clone holds.
fn rtsim_clone_only(args: &[&str], data: Option<&std::path::Path>) -> Output {
    let cwd = tmp("clone-only");
    std::fs::create_dir_all(&cwd).unwrap();
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_rtsim"));
    c.args(args).current_dir(&cwd).env_remove("RTSIM_DATA");
    if let Some(d) = data {
        c.env("RTSIM_DATA", d);
    }
    c.output().unwrap()
}

#[test]
fn a_clone_reproduces_with_only_its_own_data() {
    // A real mesh (trex: the bunny) and the volumes, from data/ alone.
    let o = rtsim_clone_only(
        &[
            "reproduce",
            "mft-table1",
            "--quick",
            "--tiles",
            "1",
            "--res",
            "64",
            "--scenes",
            "trex",
            "--format",
            "json",
        ],
        None,
    );
    let j: serde_json::Value = serde_json::from_str(&ok(&o)).unwrap();
    let rows = j["rows"].as_array().unwrap();
    assert!(rows
        .iter()
        .any(|r| r["scene"] == "trex" && r["metric"] == "hit_mismatches" && r["value"] == 0.0));
    let o = rtsim_clone_only(&["reproduce", "volume-bvh", "--quick"], None);
    assert!(ok(&o).contains("engine"));
}

#[test]
fn a_missing_data_file_says_how_to_get_it() {
    let empty = tmp("empty-data");
    std::fs::create_dir_all(&empty).unwrap();
    let e = err(&rtsim_clone_only(
        &[
            "render", "--scene", "trex", "--width", "16", "--out", "trex.png",
        ],
        Some(&empty),
    ));
    assert!(
        e.contains("meshes/stanford-bunny.obj.gz not found") && e.contains("unset RTSIM_DATA"),
        "{e}"
    );
    assert!(!tmp("clone-only").join("trex.png").exists());
    let e = err(&rtsim_clone_only(
        &["reproduce", "volume-bvh", "--quick"],
        Some(&empty),
    ));
    assert!(
        e.contains("volumes/neghip") && e.contains("RTSIM_DATA"),
        "{e}"
    );
}
