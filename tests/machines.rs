//! End-to-end tests of the timing model through the app: calibration within
//! 3% on every shipped machine, loop replay, determinism, config errors.

mod common;
use common::*;

use std::process::Output;

const MACHINES: [&str; 6] = [
    "haswell-i7-4750hq",
    "haswell-e5-2650v3",
    "larrabee",
    "core2-q6600",
    "nehalem-x5550",
    "zen3",
];

#[test]
fn calibrate_is_within_3_percent_on_every_machine() {
    for m in MACHINES {
        let j = json(&rtsim(&["calibrate", "--machine", m, "--format", "json"]));
        let rows = j["rows"].as_array().unwrap();
        assert!(rows.len() >= 40, "{m}: {} rows", rows.len());
        for r in rows {
            let (v, e) = (
                r["value"].as_f64().unwrap(),
                r["expected"].as_f64().unwrap(),
            );
            let err = (v - e).abs() / e;
            assert!(
                err <= 0.03,
                "{m} {}: {v} vs expected {e} ({:.1}%)",
                r["name"],
                err * 100.0
            );
        }
        let names: Vec<&str> = rows.iter().map(|r| r["name"].as_str().unwrap()).collect();
        for n in [
            "fma-chain",
            "pointer-chase-l1d",
            "pointer-chase-l2",
            "pointer-chase-dram",
            "stream-load-dram",
            "branch-random",
        ] {
            let sse = m.starts_with("core2") || m.starts_with("nehalem");
            if n == "fma-chain" && sse {
                continue; // SSE has no FMA: the chain is mul + add, not one class
            }
            assert!(names.contains(&n), "{m} lacks {n}");
        }
    }
}

fn per_op(file: &str, body: &str) -> f64 {
    let f = tmp(file);
    std::fs::write(&f, body).unwrap();
    let j = json(&rtsim(&[
        "sim",
        "--machine",
        "haswell-i7-4750hq",
        "--trace",
        f.to_str().unwrap(),
        "--iterations",
        "1000",
        "--format",
        "json",
    ]));
    j["rows"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["metric"] == "cycles_per_op" && r["class"] == "vfma")
        .unwrap()["value"]
        .as_f64()
        .unwrap()
}

#[test]
fn hand_written_fma_loops_replay_at_throughput_and_latency() {
    let mut ten =
        String::from(".trace 1\n.isa avx2\n# ten independent chains, each loop-carried\n");
    for c in 1..=10 {
        ten.push_str(&format!("%{c} = vfma %{c}\n"));
    }
    let v = per_op("ten.txt", &ten);
    assert!((v - 0.5).abs() < 0.01, "10 chains: {v} cycles per FMA");
    let v = per_op("one.txt", ".trace 1\n.isa avx2\n%1 = vfma %1\n");
    assert!((v - 5.0).abs() < 0.05, "1 chain: {v} cycles per FMA");
}

#[test]
fn two_runs_print_identical_numbers() {
    let strip = |o: &Output| {
        ok(o)
            .lines()
            .filter(|l| !l.contains("host"))
            .collect::<Vec<_>>()
            .join("\n")
    };
    let a = rtsim(&["run", "--rays", "512", "--format", "json"]);
    let b = rtsim(&["run", "--rays", "512", "--format", "json"]);
    assert_eq!(strip(&a), strip(&b));
    let a = rtsim(&["calibrate", "--machine", "core2-q6600", "--format", "csv"]);
    let b = rtsim(&["calibrate", "--machine", "core2-q6600", "--format", "csv"]);
    assert_eq!(strip(&a), strip(&b));
}

#[test]
fn run_times_the_default_workload() {
    let j = json(&rtsim(&["run", "--rays", "1024", "--format", "json"]));
    assert_eq!(j["machine"], "haswell-i7-4750hq");
    assert_eq!(j["fidelity"], "full");
    let rows = j["rows"].as_array().unwrap();
    let get = |m: &str| {
        rows.iter()
            .find(|r| r["metric"] == m)
            .map(|r| r["value"].as_f64().unwrap())
    };
    assert!(get("cycles").unwrap() > 0.0);
    assert!(get("mray_per_s").unwrap() > 0.0);
    assert!(rows
        .iter()
        .any(|r| r["metric"] == "cpi" && r["region"] == "core-loop"));
    let j = json(&rtsim(&[
        "run",
        "--machine",
        "larrabee",
        "--rays",
        "256",
        "--format",
        "json",
    ]));
    assert_eq!(j["isa"], "lrb16");
}

#[test]
fn fidelity_reports_each_mode_against_full() {
    let j = json(&rtsim(&["fidelity", "--rays", "1024", "--format", "json"]));
    let rows = j["rows"].as_array().unwrap();
    for mode in ["counts", "caches", "full"] {
        assert!(
            rows.iter()
                .any(|r| r["mode"] == mode && r["metric"] == "cycles_error"),
            "{mode}"
        );
    }
    let full_err = rows
        .iter()
        .find(|r| r["mode"] == "full" && r["metric"] == "cycles_error")
        .unwrap();
    assert_eq!(full_err["value"], 0.0);
}

#[test]
fn list_machines_shows_all_six() {
    let j = json(&rtsim(&["list", "machines", "--format", "json"]));
    let names: Vec<&str> = j["rows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["name"].as_str().unwrap())
        .collect();
    for m in MACHINES {
        assert!(names.contains(&m), "{m}");
    }
}

fn bad_config(name: &str, from: &str, to: &str) -> String {
    let src = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/configs/machines/haswell-i7-4750hq.ron"
    ))
    .unwrap();
    assert!(src.contains(from), "{from}");
    let f = tmp(name);
    std::fs::write(&f, src.replacen(from, to, 1)).unwrap();
    let t = tmp(&format!("{name}.txt"));
    std::fs::write(&t, ".trace 1\n.isa avx2\n%1 = vfma\n").unwrap();
    err(&rtsim(&[
        "sim",
        "--machine",
        f.to_str().unwrap(),
        "--trace",
        t.to_str().unwrap(),
    ]))
}

#[test]
fn bad_configs_name_file_line_and_field() {
    let e = bad_config("unknown.ron", "rob: 192,", "rob: 192, robb: 3,");
    assert!(
        e.contains("unknown.ron") && e.contains("line 22") && e.contains("robb"),
        "{e}"
    );
    let e = bad_config("type.ron", "rob: 192,", "rob: \"big\",");
    assert!(e.contains("type.ron") && e.contains("line 22"), "{e}");
    let e = bad_config(
        "ways.ron",
        "size_kib: 32, ways: 8,",
        "size_kib: 32, ways: 0,",
    );
    assert!(
        e.contains("ways.ron") && e.contains("caches[0].ways") && e.contains("line 75"),
        "{e}"
    );
    let e = bad_config(
        "line.ron",
        "ways: 8, line: 64, latency: 4",
        "ways: 8, line: 48, latency: 4",
    );
    assert!(
        e.contains("caches[0].line") && e.contains("power of two"),
        "{e}"
    );
    let e = bad_config(
        "port.ron",
        "\"vadd\": (lat: 3, uops: [[1]])",
        "\"vadd\": (lat: 3, uops: [[9]])",
    );
    assert!(
        e.contains("classes.vadd.uops") && e.contains("port 9") && e.contains("line 32"),
        "{e}"
    );
    let e = err(&rtsim(&[
        "calibrate",
        "--machine",
        "haswell-i7-4750hq",
        "--set",
        "core.widht=6",
    ]));
    assert!(e.contains("widht"), "{e}");
    let e = err(&rtsim(&[
        "calibrate",
        "--machine",
        "haswell-i7-4750hq",
        "--set",
        "l2.ways=0",
    ]));
    assert!(e.contains("caches[1].ways"), "{e}");
    let e = err(&rtsim(&[
        "calibrate",
        "--machine",
        "haswell-i7-4750hq",
        "--set",
        "core.rob=lots",
    ]));
    assert!(e.contains("rob") || e.contains("invalid"), "{e}");
    let e = err(&rtsim(&["calibrate", "--machine", "pentium5"]));
    assert!(
        e.contains("pentium5") && e.contains("haswell-i7-4750hq"),
        "{e}"
    );
}

#[test]
fn set_overrides_change_the_model() {
    let t = tmp("chain.txt");
    std::fs::write(&t, ".trace 1\n.isa avx2\n%1 = vfma %1\n").unwrap();
    let run = |sets: &[&str]| {
        let mut a = vec![
            "sim",
            "--trace",
            t.to_str().unwrap(),
            "--iterations",
            "100",
            "--format",
            "json",
        ];
        for s in sets {
            a.extend(["--set", s]);
        }
        let j = json(&rtsim(&a));
        j["rows"][0]["value"].as_f64().unwrap()
    };
    assert!((run(&[]) - 5.0).abs() < 0.1);
    assert!(
        (run(&["classes.vfma.lat=8"]) - 8.0).abs() < 0.1,
        "a slower FMA"
    );
}

#[test]
fn run_times_the_traversal_kernels_and_checks_their_hits() {
    for kernel in ["single-bvh2", "single-bvh4", "drs-bvh2", "drs-bvh4"] {
        for stream in ["primary", "bounce"] {
            let j = json(&rtsim(&[
                "run", "--kernel", kernel, "--scene", "sphere", "--stream", stream, "--tile", "8",
                "--spp", "4", "--format", "json",
            ]));
            let rows = j["rows"].as_array().unwrap();
            let bad: Vec<f64> = rows
                .iter()
                .filter(|r| r["metric"] == "hit_mismatches")
                .map(|r| r["value"].as_f64().unwrap())
                .collect();
            assert_eq!(bad, [0.0, 0.0], "{kernel} {stream}");
            assert!(
                rows.iter().any(|r| r["metric"] == "mray_per_s"),
                "{kernel} {stream}: timed"
            );
        }
    }
    let j = json(&rtsim(&[
        "run", "--kernel", "drs-bvh4", "--scene", "sphere", "--tile", "8", "--spp", "4",
        "--format", "json",
    ]));
    let rows = j["rows"].as_array().unwrap();
    assert!(
        rows.iter()
            .any(|r| r["metric"] == "cpi" && r["region"] == "core-loop"),
        "the DRS core loop is timed apart"
    );
    let e = err(&rtsim(&[
        "run",
        "--kernel",
        "drs-bvh4",
        "--machine",
        "larrabee",
    ]));
    assert!(e.contains("4- and 8-lane"), "{e}");
    let e = err(&rtsim(&["run", "--kernel", "warp-drive"]));
    assert!(e.contains("warp-drive"), "{e}");
}

#[test]
fn reproduce_drs_table2_computes_every_cell_on_a_small_sample() {
    let j = json(&rtsim(&[
        "reproduce",
        "drs-table2",
        "--quick",
        "--tiles",
        "1",
        "--spp",
        "2",
        "--format",
        "json",
    ]));
    assert_eq!(j["machine"], "haswell-i7-4750hq");
    assert_eq!(j["sample"]["tiles_per_scene"], 1);
    let rows = j["rows"].as_array().unwrap();
    let get = |scene: &str, method: &str, metric: &str| -> f64 {
        let r: Vec<&serde_json::Value> = rows
            .iter()
            .filter(|r| {
                r["scene"] == scene
                    && r["method"] == method
                    && r["metric"] == metric
                    && r.get("region").is_none()
            })
            .collect();
        assert_eq!(r.len(), 1, "{scene} {method} {metric}");
        r[0]["value"].as_f64().unwrap()
    };
    for scene in ["crown", "bentley", "dragon", "sanmiguel"] {
        for method in ["single-bvh4", "drs-bvh4"] {
            assert_eq!(
                get(scene, method, "hit_mismatches"),
                0.0,
                "{scene} {method}"
            );
            assert!(get(scene, method, "s_per_gray") > 0.0);
            assert!(
                get(scene, method, "cpi") > 0.25,
                "{scene} {method}: CPI >= 1/width"
            );
        }
        let share = get(scene, "drs-bvh4", "core_loop_share");
        assert!(share > 0.0 && share <= 1.0, "{scene}: {share}");
        assert!(
            get(scene, "drs-bvh4", "core_loop_cpi") < get(scene, "drs-bvh4", "cpi"),
            "{scene}: the core loop has the lowest CPI"
        );
    }
    assert!(
        rows.iter().filter(|r| r.get("paper").is_some()).count() >= 4 * 7,
        "the paper's figures beside ours"
    );
    let notes = j["notes"].as_array().unwrap();
    assert!(
        notes
            .iter()
            .any(|n| n.as_str().unwrap().starts_with("dragon: Our BVH4")),
        "each scene's comparison with the paper is spelled out: {notes:?}"
    );
    let e = err(&rtsim(&["reproduce", "drs-table9"]));
    assert!(e.contains("unknown report 'drs-table9'"), "{e}");
}

#[test]
fn reproduce_drs_table1_computes_all_seven_rows() {
    let j = json(&rtsim(&[
        "reproduce",
        "drs-table1",
        "--tiles",
        "1",
        "--spp",
        "1",
        "--format",
        "json",
    ]));
    let rows = j["rows"].as_array().unwrap();
    for scene in ["crown", "bentley", "dragon", "sanmiguel"] {
        for method in [
            "drs-bvh2",
            "drs-bvh4",
            "single-bvh2",
            "single-bvh4",
            "packet-bvh2",
            "packet-bvh4",
            "hybrid-bvh4",
        ] {
            let of = |metric: &str| -> Vec<&serde_json::Value> {
                rows.iter()
                    .filter(|r| {
                        r["scene"] == scene
                            && r["method"] == method
                            && r["metric"] == metric
                            && r.get("stream").is_none()
                    })
                    .collect()
            };
            assert_eq!(of("hit_mismatches")[0]["value"], 0.0, "{scene} {method}");
            let m = of("mray_per_s");
            assert!(m[0]["value"].as_f64().unwrap() > 0.0, "{scene} {method}");
            assert!(
                m[0]["paper"].as_f64().is_some(),
                "{scene} {method}: paper beside"
            );
            assert!(of("bytes_per_ray")[0]["value"].as_f64().unwrap() > 0.0);
        }
        assert!(
            rows.iter()
                .any(|r| r["scene"] == scene && r["metric"] == "traversal_improvement"),
            "{scene}"
        );
    }
    // Shadow rays are traced by every kernel wherever the sampled tile has hits.
    for method in ["drs-bvh4", "single-bvh4", "packet-bvh4", "hybrid-bvh4"] {
        assert!(
            rows.iter()
                .any(|r| r["method"] == method && r["stream"] == "shadow"),
            "{method}: shadow rays traced"
        );
    }
    let notes = j["notes"].as_array().unwrap();
    assert!(
        notes
            .iter()
            .any(|n| n.as_str().unwrap().contains("packets are formed")),
        "how packets are formed is said: {notes:?}"
    );
}

#[test]
fn reproduce_drs_figures_write_their_table_and_plot() {
    let dir = std::env::temp_dir().join(format!("rtsim-figs-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let d = dir.to_str().unwrap();
    let j = json(&rtsim(&[
        "reproduce",
        "drs-fig6",
        "--quick",
        "--tiles",
        "1",
        "--spp",
        "1",
        "--format",
        "json",
        "--out",
        d,
    ]));
    let rows = j["rows"].as_array().unwrap();
    for method in ["drs-bvh4", "single-bvh4", "hybrid-bvh4"] {
        let n = rows
            .iter()
            .filter(|r| r["method"] == method && r["metric"] == "mray_per_s")
            .filter(|r| r["value"].as_f64().unwrap() > 0.0)
            .count();
        assert_eq!(n, 8, "{method}: one rate per FOV");
    }
    let png = std::fs::read(dir.join("drs-fig6.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    assert!(dir.join("drs-fig6.json").exists());
    let j = json(&rtsim(&[
        "reproduce",
        "drs-fig5",
        "--quick",
        "--tiles",
        "1",
        "--spp",
        "1",
        "--format",
        "json",
        "--out",
        d,
    ]));
    let rows = j["rows"].as_array().unwrap();
    for scene in ["crown", "bentley", "dragon", "sanmiguel"] {
        let tiles: Vec<&str> = rows
            .iter()
            .filter(|r| r["scene"] == scene && r["metric"] == "bytes_per_ray")
            .map(|r| r["tile"].as_str().unwrap())
            .collect();
        assert_eq!(
            tiles,
            ["4x4", "8x8", "12x12", "16x16", "20x20", "24x24", "28x28"]
        );
    }
    assert!(rows
        .iter()
        .filter(|r| r["metric"] == "hit_mismatches")
        .all(|r| r["value"] == 0.0));
    assert!(std::fs::read(dir.join("drs-fig5.png"))
        .unwrap()
        .starts_with(b"\x89PNG"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn reproduce_mft_table1_counts_every_cell_and_frusta_cut_box_tests() {
    let j = quick_report("mft-table1", None);
    assert_eq!(j["machine"], "larrabee", "defaults to the 16-lane machine");
    let rows = j["rows"].as_array().unwrap();
    let get = |scene: &str, method: &str, metric: &str| -> f64 {
        let r: Vec<&serde_json::Value> = rows
            .iter()
            .filter(|r| r["scene"] == scene && r["method"] == method && r["metric"] == metric)
            .collect();
        assert_eq!(r.len(), 1, "{scene} {method} {metric}");
        r[0]["value"].as_f64().unwrap()
    };
    for scene in ["trex", "fern", "saloon", "fairy"] {
        for method in ["p-packet", "p-frusta", "s-packet", "s-frusta"] {
            assert_eq!(
                get(scene, method, "hit_mismatches"),
                0.0,
                "{scene} {method}"
            );
            for metric in ["tris_accessed", "aabb_tests", "isec_tests", "cycles"] {
                assert!(
                    get(scene, method, metric) > 0.0,
                    "{scene} {method} {metric}"
                );
            }
        }
        assert!(
            get(scene, "p-packet", "aabb_tests") > 4.0 * get(scene, "p-frusta", "aabb_tests"),
            "{scene}: frusta cut box tests"
        );
    }
}

#[test]
fn reproduce_mft_packet256_checks_hits_and_counts_both_methods() {
    let j = quick_report("mft-packet256", None);
    let rows = j["rows"].as_array().unwrap();
    for method in ["packet256", "p-frusta", "s-frusta"] {
        let n = rows
            .iter()
            .filter(|r| r["method"] == method && r["metric"] == "cycles")
            .filter(|r| r["value"].as_f64().unwrap() > 0.0)
            .count();
        assert!(n >= 4, "{method}: cycles on every scene ({n})");
    }
    assert!(rows
        .iter()
        .filter(|r| r["metric"] == "hit_mismatches")
        .all(|r| r["value"] == 0.0));
}

#[test]
fn reproduce_mft_table2_shrinking_keeps_hits_and_cr_keeps_traversal() {
    let j = quick_report("mft-table2", None);
    assert_eq!(j["machine"], "larrabee");
    let rows = j["rows"].as_array().unwrap();
    let get = |shrink: &str, metric: &str| -> f64 {
        let r: Vec<&serde_json::Value> = rows
            .iter()
            .filter(|r| r["shrink"] == shrink && r["metric"] == metric)
            .collect();
        assert_eq!(r.len(), 1, "{shrink} {metric}");
        r[0]["value"].as_f64().unwrap()
    };
    for s in ["no-shrink", "ray-aabb", "cr", "fs"] {
        assert_eq!(get(s, "hit_mismatches"), 0.0, "{s}");
        assert!(get(s, "cycles") > 0.0, "{s}");
    }
    // CR recomputes corners only: traversal and fetches unchanged, fewer
    // triangles survive culling; Ray-AABB adds box tests.
    assert_eq!(get("cr", "aabb_tests"), get("no-shrink", "aabb_tests"));
    assert_eq!(
        get("cr", "tris_accessed"),
        get("no-shrink", "tris_accessed")
    );
    assert!(get("cr", "tris_after_culling") < get("no-shrink", "tris_after_culling"));
    assert!(get("cr", "addl_tests") > 0.0);
    assert!(get("ray-aabb", "aabb_tests") > get("no-shrink", "aabb_tests"));
    assert!(get("fs", "tris_accessed") <= get("no-shrink", "tris_accessed"));
}

#[test]
fn reproduce_mft_quality_writes_images_and_the_filter_pays() {
    let dir = std::env::temp_dir().join(format!("rtsim-mftq-{}", std::process::id()));
    let j = quick_report("mft-quality", Some(&dir));
    let rows = j["rows"].as_array().unwrap();
    let get = |method: &str, metric: &str| -> f64 {
        let r: Vec<&serde_json::Value> = rows
            .iter()
            .filter(|r| r["method"] == method && r["metric"] == metric)
            .collect();
        assert_eq!(r.len(), 1, "{method} {metric}");
        r[0]["value"].as_f64().unwrap()
    };
    assert_eq!(get("mft", "hit_mismatches"), 0.0);
    assert_eq!(get("reference", "hit_mismatches"), 0.0);
    // 16 interleaved samples need the 4 x 4 filter to approach 256 samples.
    let (f, raw) = (get("mft", "psnr"), get("mft-unfiltered", "psnr"));
    assert!(
        f > raw + 3.0 && f > 30.0,
        "filtered {f} dB, unfiltered {raw} dB"
    );
    assert!(get("mft", "cycles") < get("reference", "cycles"));
    for name in ["mft", "mft-unfiltered", "reference", "diff4x"] {
        let p = dir.join(format!("mft-quality-{name}.png"));
        assert!(std::fs::read(&p).unwrap().starts_with(b"\x89PNG"), "{name}");
    }
    assert!(dir.join("mft-quality.json").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn reproduce_mft_fig6_counts_grow_with_the_light() {
    let dir = std::env::temp_dir().join(format!("rtsim-fig6-{}", std::process::id()));
    let j = quick_report("mft-fig6", Some(&dir));
    let rows = j["rows"].as_array().unwrap();
    for scene in ["trex", "fern", "saloon"] {
        let tris: Vec<f64> = rows
            .iter()
            .filter(|r| {
                r["scene"] == scene && r["method"] == "s-frusta" && r["metric"] == "tris_accessed"
            })
            .map(|r| r["value"].as_f64().unwrap())
            .collect();
        assert_eq!(tris.len(), 5, "{scene}");
        assert!(tris.windows(2).all(|w| w[1] > w[0]), "{scene}: {tris:?}");
        // The paper's Figure 6: linear in the light's size.
        for metric in ["tris_accessed_linear_r2", "isec_tests_linear_r2"] {
            let r2 = rows
                .iter()
                .find(|r| r["scene"] == scene && r["metric"] == metric)
                .unwrap()["value"]
                .as_f64()
                .unwrap();
            assert!(r2 > 0.9, "{scene} {metric} {r2}");
        }
    }
    assert!(std::fs::read(dir.join("mft-fig6.png"))
        .unwrap()
        .starts_with(b"\x89PNG"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// `rtsim reproduce NAME --quick --tiles 1 --format json [--out DIR]`, parsed.
fn quick_report(name: &str, dir: Option<&std::path::Path>) -> serde_json::Value {
    let d = dir.map(|d| d.to_str().unwrap().to_string());
    let mut args = vec![
        "reproduce",
        name,
        "--quick",
        "--tiles",
        "1",
        "--format",
        "json",
    ];
    if let Some(d) = &d {
        args.extend(["--out", d.as_str()]);
    }
    json(&rtsim(&args))
}
