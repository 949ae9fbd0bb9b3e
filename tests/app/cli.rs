//! End-to-end tests of the `rtsim` app: the acceptance commands, bad
//! input, and golden op streams (one op per line; `RTSIM_BLESS=1` rewrites them).

use crate::common::*;

use std::path::Path;

fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

#[test]
fn record_twice_is_byte_identical_and_info_counts_classes() {
    let (a, b) = (tmp("a.rtt"), tmp("b.rtt"));
    ok(&rtsim(&[
        "trace",
        "record",
        "--micro",
        "fma-chain",
        "--isa",
        "avx2",
        "--out",
        p(&a),
    ]));
    ok(&rtsim(&[
        "trace",
        "record",
        "--micro",
        "fma-chain",
        "--isa",
        "avx2",
        "--out",
        p(&b),
    ]));
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    let j: serde_json::Value =
        serde_json::from_str(&ok(&rtsim(&["trace", "info", p(&a), "--format", "json"]))).unwrap();
    assert_eq!(j["report"], "trace-info");
    let rows = j["rows"].as_array().unwrap();
    let class = |c: &str| {
        rows.iter()
            .find(|r| r["class"] == c && r["metric"] == "ops")
            .map(|r| r["value"].as_f64().unwrap())
    };
    // 1000 iterations of 8 dependent FMAs and the loop's add, compare, branch.
    assert_eq!(class("vfma"), Some(8000.0));
    assert_eq!(class("alu"), Some(1000.0));
    assert_eq!(class("branch"), Some(1000.0));
    assert_eq!(j["ops_simulated"], 11000);
}

#[test]
fn corrupt_truncated_and_wrong_version_files_exit_2_naming_the_file() {
    let a = tmp("c.rtt");
    ok(&rtsim(&[
        "trace",
        "record",
        "--micro",
        "add-streams",
        "--isa",
        "sse4",
        "--out",
        p(&a),
    ]));
    let good = std::fs::read(&a).unwrap();
    for (i, name) in [
        (40usize, "flip1.rtt"),
        (good.len() / 2, "flip2.rtt"),
        (good.len() - 3, "flip3.rtt"),
    ] {
        let mut b = good.clone();
        b[i] ^= 0x04;
        let f = tmp(name);
        std::fs::write(&f, &b).unwrap();
        let e = err(&rtsim(&["trace", "info", p(&f)]));
        assert!(e.contains(name) && e.contains("byte "), "{e}");
    }
    let f = tmp("trunc.rtt");
    std::fs::write(&f, &good[..good.len() - 20]).unwrap();
    assert!(err(&rtsim(&["trace", "info", p(&f)])).contains("trunc.rtt"));
    let mut v = good.clone();
    v[8] = 9;
    let f = tmp("ver.rtt");
    std::fs::write(&f, &v).unwrap();
    assert!(err(&rtsim(&["trace", "info", p(&f)])).contains("version 9"));
    let f = tmp("missing.rtt");
    assert!(err(&rtsim(&["trace", "info", p(&f)])).contains("missing.rtt"));
}

#[test]
fn text_conversion_round_trips_byte_for_byte() {
    let (a, t, b) = (tmp("r.rtt"), tmp("r.txt"), tmp("r2.rtt"));
    ok(&rtsim(&[
        "trace",
        "record",
        "--kernel",
        "boxtest",
        "--isa",
        "lrb16",
        "--param",
        "rays=64",
        "--out",
        p(&a),
    ]));
    ok(&rtsim(&["trace", "text", p(&a), p(&t)]));
    ok(&rtsim(&["trace", "text", p(&t), p(&b)]));
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    let text = std::fs::read_to_string(&t).unwrap();
    assert!(
        text.starts_with("# rtsim trace")
            && text.contains(".isa lrb16")
            && text.contains("%1 = vloadbcast"),
        "{text}"
    );
}

#[test]
fn hand_written_text_trace_is_read_and_bad_lines_are_named() {
    let f = tmp("hand.txt");
    std::fs::write(
        &f,
        ".trace 1\n.isa avx2\n.source hand:fma\n%1 = vfma\n%2 = vfma %1\n%3 = vfma %2\n",
    )
    .unwrap();
    let out = ok(&rtsim(&["trace", "info", p(&f), "--format", "csv"]));
    assert!(out.contains("vfma,,ops,3,ops"), "{out}");
    std::fs::write(&f, ".trace 1\n.isa avx2\n%1 = vfma\n%2 = vfam %1\n").unwrap();
    let e = err(&rtsim(&["trace", "info", p(&f)]));
    assert!(e.contains("hand.txt: line 4") && e.contains("vfam"), "{e}");
    std::fs::write(&f, ".trace 1\n.isa avx2\n%2 = vfma %1\n").unwrap();
    let e = err(&rtsim(&["trace", "info", p(&f)]));
    assert!(e.contains("not defined before use"), "{e}");
}

#[test]
fn run_checks_every_ray_on_every_isa() {
    for isa in ["lrb16", "avx512", "avx2", "sse4"] {
        let j: serde_json::Value = serde_json::from_str(&ok(&rtsim(&[
            "run", "--kernel", "boxtest", "--isa", isa, "--rays", "256", "--format", "json",
        ])))
        .unwrap();
        let rows = j["rows"].as_array().unwrap();
        let bad: Vec<f64> = rows
            .iter()
            .filter(|r| r["metric"] == "hit_mismatches")
            .map(|r| r["value"].as_f64().unwrap())
            .collect();
        assert_eq!(bad, [0.0, 0.0], "{isa}");
        assert_eq!(j["isa"], isa);
    }
}

#[test]
fn bad_arguments_exit_2_without_writing() {
    let out = tmp("never.rtt");
    assert!(err(&rtsim(&["run", "--kernel", "boxtest", "--rays", "3"])).contains("rays"));
    // --rays is boxtest's: a traversal kernel traces a tile's stream.
    let e = err(&rtsim(&["run", "--kernel", "drs-bvh4", "--rays", "64"]));
    assert!(e.contains("only the boxtest kernel"), "{e}");
    let e = err(&rtsim(&["run", "--kernel", "drs-bvh4,warp-drive"]));
    assert!(e.contains("warp-drive"), "{e}");
    assert!(err(&rtsim(&["run", "--isa", "avx9"])).contains("avx9"));
    let e = err(&rtsim(&[
        "trace",
        "record",
        "--micro",
        "fma-chian",
        "--out",
        p(&out),
    ]));
    assert!(e.contains("fma-chian"), "{e}");
    let e = err(&rtsim(&[
        "trace",
        "record",
        "--micro",
        "fma-chain",
        "--param",
        "iters=0",
        "--out",
        p(&out),
    ]));
    assert!(e.contains("iters"), "{e}");
    let e = err(&rtsim(&[
        "trace",
        "record",
        "--micro",
        "fma-chain",
        "--param",
        "iters",
        "--out",
        p(&out),
    ]));
    assert!(e.contains("KEY=VALUE"), "{e}");
    assert!(!out.exists(), "nothing half-written");
    let e = err(&rtsim(&[
        "trace",
        "record",
        "--micro",
        "fma-chain",
        "--out",
        "/nonexistent-dir/x.rtt",
    ]));
    assert!(e.contains("/nonexistent-dir/x.rtt"), "{e}");
}

#[test]
fn list_micro_names_every_microkernel() {
    let j: serde_json::Value =
        serde_json::from_str(&ok(&rtsim(&["list", "micro", "--format", "json"]))).unwrap();
    let names: Vec<&str> = j["rows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["name"].as_str().unwrap())
        .collect();
    for n in [
        "fma-chain",
        "fma-streams",
        "pointer-chase",
        "stream-load",
        "stream-store",
        "branch-predictable",
        "branch-random",
    ] {
        assert!(names.contains(&n), "{n}");
    }
}

fn golden(name: &str, args: &[&str]) {
    let f = tmp(&format!("{name}.txt"));
    let mut a: Vec<&str> = args.to_vec();
    a.extend(["--out", p(&f)]);
    ok(&rtsim(&a));
    let got = std::fs::read_to_string(&f).unwrap();
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("traces/golden")
        .join(format!("{name}.txt"));
    if std::env::var_os("RTSIM_BLESS").is_some() {
        std::fs::write(&path, &got).unwrap();
    }
    let want = std::fs::read_to_string(&path)
        .unwrap_or_else(|_| panic!("{} missing: run with RTSIM_BLESS=1", path.display()));
    if got != want {
        let line = got
            .lines()
            .zip(want.lines())
            .position(|(g, w)| g != w)
            .unwrap_or(0);
        panic!(
            "{name}: op stream differs from {} at line {}:\n  got:  {}\n  want: {}",
            path.display(),
            line + 1,
            got.lines().nth(line).unwrap_or(""),
            want.lines().nth(line).unwrap_or("")
        );
    }
}

#[test]
fn golden_op_streams() {
    golden(
        "fma-chain-avx2",
        &[
            "trace",
            "record",
            "--micro",
            "fma-chain",
            "--isa",
            "avx2",
            "--param",
            "iters=2",
            "--param",
            "unroll=4",
        ],
    );
    golden(
        "pointer-chase-avx2",
        &[
            "trace",
            "record",
            "--micro",
            "pointer-chase",
            "--isa",
            "avx2",
            "--param",
            "iters=8",
            "--param",
            "ws=1K",
        ],
    );
    for isa in ["avx2", "sse4", "lrb16"] {
        golden(
            &format!("boxtest-{isa}"),
            &[
                "trace", "record", "--kernel", "boxtest", "--isa", isa, "--param", "rays=8",
            ],
        );
    }
}

/// Every report of the papers' registries.
const REPORTS: [&str; 22] = [
    "drs-table1",
    "drs-table2",
    "drs-fig5",
    "drs-fig6",
    "mft-table1",
    "mft-table2",
    "mft-packet256",
    "mft-quality",
    "mft-fig6",
    "mft-loose",
    "mbvh-fig2",
    "mbvh-fig3",
    "mbvh-fig4-6",
    "mbvh-fig7-8",
    "mbvh-table1-2",
    "multihit-fig2",
    "multihit-summary",
    "volume-fig5",
    "volume-table1",
    "volume-fig6",
    "volume-fig7",
    "volume-bvh",
];

#[test]
fn every_report_is_listed_and_reached_through_the_cli_with_its_options_checked() {
    let help = ok(&rtsim(&["reproduce", "--help"]));
    for name in REPORTS {
        assert!(help.contains(&format!("{name}: ")), "{name} in --help");
        // The report is dispatched and checks its options before computing.
        let e = err(&rtsim(&["reproduce", name, "--quick", "--tiles", "0"]));
        assert!(e.contains("--tiles: "), "{name}: {e}");
        let e = err(&rtsim(&["reproduce", name, "--spp", "0"]));
        assert!(e.contains("--spp"), "{name}: {e}");
        let e = err(&rtsim(&["reproduce", name, "--res", "100"]));
        assert!(e.contains("--res"), "{name}: {e}");
    }
    // Hardware threads per core: the machine's, checked before computing.
    let e = err(&rtsim(&[
        "reproduce",
        "drs-table2",
        "--threads-per-core",
        "3",
    ]));
    assert!(
        e.contains("--threads-per-core: 3 is not 1 to 2") && e.contains("core.threads"),
        "{e}"
    );
    let e = err(&rtsim(&[
        "reproduce",
        "drs-table2",
        "--threads-per-core",
        "2",
        "--machine",
        "core2-q6600",
    ]));
    assert!(e.contains("is not 1 to 1"), "{e}");
    for name in REPORTS.iter().filter(|n| n.starts_with("mft")) {
        let e = err(&rtsim(&["reproduce", name, "--spp", "4"]));
        assert!(e.contains("--spp: ") && e.contains("does not use"), "{e}");
        let e = err(&rtsim(&["reproduce", name, "--threads-per-core", "2"]));
        assert!(
            e.contains("--threads-per-core: ") && e.contains("does not use"),
            "{e}"
        );
        let e = err(&rtsim(&[
            "reproduce",
            name,
            "--machine",
            "haswell-i7-4750hq",
        ]));
        assert!(e.contains("16 lanes"), "{name}: {e}");
    }
    // The MBVH rates are the paper's 4-wide SSE figures.
    let e = err(&rtsim(&["reproduce", "mbvh-fig3", "--machine", "larrabee"]));
    assert!(e.contains("4-wide"), "{e}");
    // The multi-hit kernels are the paper's 8-wide ispc modules.
    let e = err(&rtsim(&[
        "reproduce",
        "multihit-fig2",
        "--machine",
        "larrabee",
    ]));
    assert!(e.contains("8-wide"), "{e}");
    // Listing 2 is 4-wide SSE.
    let e = err(&rtsim(&[
        "reproduce",
        "volume-fig5",
        "--machine",
        "larrabee",
    ]));
    assert!(e.contains("4-wide"), "{e}");
    let e = err(&rtsim(&["reproduce", "drs-table9"]));
    assert!(e.contains("unknown report 'drs-table9'"), "{e}");
}

#[test]
fn a_report_prints_and_writes_the_same_json_with_overrides_on_its_own_machine() {
    let dir = tmp("report-out");
    let d = dir.to_str().unwrap();
    let o = rtsim(&[
        "reproduce",
        "mft-table2",
        "--quick",
        "--tiles",
        "1",
        "--set",
        "core.ports=2",
        "--format",
        "json",
        "--out",
        d,
    ]);
    let printed = json(&o);
    assert_eq!(printed["machine"], "larrabee");
    let written: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("mft-table2.json")).unwrap()).unwrap();
    assert_eq!(printed, written);
}

#[test]
fn run_lists_every_kernel_and_out_writes_the_trace_of_each() {
    let help = ok(&rtsim(&["run", "--help"]));
    let kernels = [
        "boxtest",
        "drs-bvh2",
        "drs-bvh4",
        "single-bvh2",
        "single-bvh4",
        "packet-bvh2",
        "packet-bvh4",
        "hybrid-bvh4",
    ];
    for k in kernels {
        assert!(help.contains(k), "{k} in run --help");
    }
    for k in ["single-bvh4", "drs-bvh2"] {
        let f = tmp(&format!("{k}.txt"));
        let j = json(&rtsim(&[
            "run",
            "--kernel",
            k,
            "--scene",
            "sphere",
            "--tile",
            "4",
            "--spp",
            "1",
            "--out",
            p(&f),
            "--format",
            "json",
        ]));
        let rows = j["rows"].as_array().unwrap();
        let bytes = rows.iter().find(|r| r["metric"] == "trace_bytes").unwrap();
        assert_eq!(bytes["value"], std::fs::metadata(&f).unwrap().len() as f64);
        let info = json(&rtsim(&["trace", "info", p(&f), "--format", "json"]));
        assert_eq!(info["ops_simulated"], j["ops_simulated"], "{k}");
    }
}

#[test]
fn a_zero_latency_override_is_an_error_naming_the_field() {
    let e = err(&rtsim(&["calibrate", "--set", "classes.vfma.lat=0"]));
    assert!(e.contains("classes.vfma.lat"), "{e}");
}

#[test]
fn native_times_every_kernel_on_the_same_rays_and_checks_them() {
    let j = json(&rtsim(&[
        "native", "--scene", "sphere", "--tile", "8", "--spp", "2", "--repeat", "3", "--format",
        "json",
    ]));
    assert_eq!(j["report"], "native");
    let rows = j["rows"].as_array().unwrap();
    let of = |method: &str, metric: &str| {
        rows.iter()
            .find(|r| r["method"] == method && r["metric"] == metric)
            .and_then(|r| r["value"].as_f64())
    };
    for k in [
        "drs-bvh2",
        "drs-bvh4",
        "single-bvh4",
        "packet-bvh4",
        "hybrid-bvh4",
    ] {
        assert_eq!(of(k, "hit_mismatches"), Some(0.0), "{k}");
        let (lo, mid, hi) = (
            of(k, "mray_per_s_slowest").unwrap(),
            of(k, "mray_per_s").unwrap(),
            of(k, "mray_per_s_fastest").unwrap(),
        );
        assert!(lo > 0.0 && lo <= mid && mid <= hi, "{k}: {lo} {mid} {hi}");
    }
    assert_eq!(of("single-bvh4", "time_vs_base"), Some(1.0));
    // The hand-written twin of single-bvh4 where the host runs AVX2 + FMA
    // (the default ISA on this build's hosts is avx2).
    // Its node test in 4-lane registers, and in 8-lane ones (`-ymm`).
    for twin in ["hand-single-bvh4", "hand-single-bvh4-ymm"] {
        if let Some(bad) = of(twin, "hit_mismatches") {
            assert_eq!(bad, 0.0);
            assert!(of(twin, "time_vs_base").unwrap() > 0.0);
        }
    }
    assert_eq!(
        of("hand-single-bvh4", "hit_mismatches").is_some(),
        of("hand-single-bvh4-ymm", "hit_mismatches").is_some(),
        "both twins or neither"
    );
    let embree = of("embree-1m", "hit_mismatches");
    assert_eq!(embree.is_some(), embree_peer::available().is_ok());
    assert!(j["input"].as_str().unwrap().contains("host "));
    let e = err(&rtsim(&["native", "--kernel", "drs-bvh9"]));
    assert!(e.contains("drs-bvh9"), "{e}");
    let e = err(&rtsim(&["native", "--repeat", "0"]));
    assert!(e.contains("--repeat"), "{e}");
    let e = err(&rtsim(&["native", "--isa", "avx1024"]));
    assert!(e.contains("avx1024"), "{e}");
    // Embree's device settings: checked (Embree ignores unknown keys), and
    // refused on a host without Embree 3.
    for (c, says) in [
        ("tri_accel=bvh4.triangle4,foo=1", "unknown key \"foo\""),
        ("tri_accel", "not key=value"),
        ("isa=", "value"),
    ] {
        let e = err(&rtsim(&[
            "native",
            "--scene",
            "sphere",
            "--embree-config",
            c,
        ]));
        let want = if embree_peer::available().is_ok() {
            says
        } else {
            "Embree 3 not found"
        };
        assert!(
            e.contains("--embree-config") && e.contains(want),
            "{c}: {e}"
        );
    }
}

#[test]
fn native_builds_embree_as_its_device_config_says() {
    if let Err(why) = embree_peer::available() {
        eprintln!("skipped: {why}");
        return;
    }
    let j = json(&rtsim(&[
        "native",
        "--scene",
        "sphere",
        "--kernel",
        "single-bvh4",
        "--tile",
        "8",
        "--spp",
        "1",
        "--repeat",
        "1",
        "--embree-config",
        "tri_accel=bvh4.triangle4",
        "--format",
        "json",
    ]));
    let rows = j["rows"].as_array().unwrap();
    let bad = rows
        .iter()
        .find(|r| r["method"] == "embree-1" && r["metric"] == "hit_mismatches");
    assert_eq!(bad.and_then(|r| r["value"].as_f64()), Some(0.0));
    let notes = j["notes"].to_string();
    assert!(
        notes.contains("threads=1,tri_accel=bvh4.triangle4"),
        "{notes}"
    );
    let e = err(&rtsim(&[
        "native",
        "--scene",
        "sphere",
        "--embree-config",
        "tri_accel=bvh9.nothing",
    ]));
    assert!(
        e.contains("--embree-config") && e.contains("bvh9.nothing"),
        "{e}"
    );
}

/// `rtsim validate` on `machine` over sphere's `streams` of a 4-pixel tile
/// at 2 spp, one timed run: its JSON.
fn validate_sphere(machine: &str, streams: &[&str]) -> serde_json::Value {
    let mut args = vec!["validate", "--scene", "sphere"];
    for s in streams {
        args.extend(["--stream", s]);
    }
    args.extend(["--tile", "4", "--spp", "2", "--repeat", "1"]);
    args.extend(["--machine", machine, "--format", "json"]);
    json(&rtsim(&args))
}

#[test]
fn validate_sets_native_beside_the_model_and_ranks_them() {
    let j = validate_sphere("zen3", &["primary", "shadow"]);
    assert_eq!(j["report"], "validate");
    assert_eq!(j["machine"], "zen3");
    let rows = j["rows"].as_array().unwrap();
    let count = |metric: &str| rows.iter().filter(|r| r["metric"] == metric).count();
    // Single-bvh4's hand-written twins (4- and 8-lane node tests) on both
    // streams where the host runs AVX2 + FMA; Embree's three calls on both
    // with the feature.
    let hand = rows
        .iter()
        .filter(|r| r["metric"] == "native_mray_per_s")
        .filter(|r| {
            r["method"]
                .as_str()
                .unwrap()
                .starts_with("hand-single-bvh4")
        })
        .count();
    assert!(hand == 0 || hand == 4, "{hand}");
    assert_eq!(
        count("native_mray_per_s"),
        14 + hand
            + if embree_peer::available().is_ok() {
                6
            } else {
                0
            }
    );
    assert_eq!(count("model_mray_per_s"), 14);
    assert_eq!(count("relative_error"), 12, "every kernel but the baseline");
    let overall = |metric: &str| {
        rows.iter()
            .find(|r| r["metric"] == metric && r["scene"] == "all")
            .and_then(|r| r["value"].as_f64())
            .unwrap()
    };
    assert!((-1.0..=1.0).contains(&overall("kendall_tau")));
    assert!(overall("mean_abs_relative_error") >= 0.0);
    // With the twin as the native base: every kernel's point, single-bvh4's
    // included, and the overall figures.
    assert_eq!(
        count("relative_error_over_twin"),
        if hand > 0 { 14 } else { 0 }
    );
    if hand > 0 {
        assert!((-1.0..=1.0).contains(&overall("kendall_tau_over_twin")));
        assert!(overall("mean_abs_relative_error_over_twin") >= 0.0);
    }
    let e = err(&rtsim(&[
        "validate",
        "--machine",
        "zen4",
        "--set",
        "isa=wide32",
        "--scene",
        "sphere",
    ]));
    assert!(e.contains("lanes"), "{e}");
    let e = err(&rtsim(&[
        "validate",
        "--machine",
        "zen3",
        "--stream",
        "sideways",
    ]));
    assert!(e.contains("sideways"), "{e}");
}

#[test]
fn validate_runs_the_16_lane_flavour_on_its_model() {
    let j = validate_sphere("zen4-avx512", &["primary"]);
    assert_eq!(j["isa"], "avx512");
    let rows = j["rows"].as_array().unwrap();
    // Every kernel natively and on the model; no hand-written twin (its
    // node test is 4 or 8 lanes wide).
    let model = rows.iter().filter(|r| r["metric"] == "model_mray_per_s");
    assert_eq!(model.count(), 7);
    assert!(!rows
        .iter()
        .any(|r| r["metric"] == "relative_error_over_twin"));
}

#[test]
fn sweep_times_a_kernel_on_a_two_field_grid_and_plots_it() {
    let dir = tmp("sweep-out");
    let _ = std::fs::remove_dir_all(&dir);
    let args = [
        "sweep",
        "--kernel",
        "drs-bvh4",
        "--scene",
        "sphere",
        "--stream",
        "primary",
        "--tile",
        "4",
        "--spp",
        "2",
        "--vary",
        "isa=sse4,avx2",
        "--vary",
        "core.width=1,4",
        "--out",
        p(&dir),
        "--format",
        "json",
    ];
    let j = json(&rtsim(&args));
    assert_eq!(j["report"], "sweep");
    let rows = j["rows"].as_array().unwrap();
    let cycles = |isa: &str, w: &str| {
        rows.iter()
            .find(|r| r["metric"] == "cycles" && r["isa"] == isa && r["core.width"] == w)
            .and_then(|r| r["value"].as_f64())
            .unwrap()
    };
    for isa in ["sse4", "avx2"] {
        assert!(
            cycles(isa, "1") > cycles(isa, "4"),
            "{isa}: one-wide is slower"
        );
    }
    assert_eq!(
        rows.iter().filter(|r| r["metric"] == "mray_per_s").count(),
        4
    );
    assert!(dir.join("sweep.png").exists());
    let again = json(&rtsim(&args));
    assert_eq!(again["rows"], j["rows"], "deterministic");
    for (bad, says) in [
        ("core.widht=1,2", "widht"),
        ("core.width=0,2", "core.width"),
        ("core.width=2,2", "twice"),
        ("isa=avx1024", "avx1024"),
        ("core.width", "FIELD=V1"),
    ] {
        let e = err(&rtsim(&["sweep", "--scene", "sphere", "--vary", bad]));
        assert!(e.contains(says), "{bad}: {e}");
    }
}

#[test]
fn sweep_runs_a_reports_cells_on_a_grid_and_plots_them() {
    let dir = tmp("sweep-report-out");
    let _ = std::fs::remove_dir_all(&dir);
    let args = [
        "sweep",
        "--report",
        "mft-table2",
        "--quick",
        "--res",
        "64",
        "--tiles",
        "2",
        "--metric",
        "cycles",
        "--vary",
        "core.width=1,2",
        "--out",
        p(&dir),
        "--format",
        "json",
    ];
    let j = json(&rtsim(&args));
    assert_eq!(j["report"], "sweep-mft-table2");
    let rows = j["rows"].as_array().unwrap();
    assert!(rows.iter().all(|r| r["metric"] == "cycles"));
    // Every cell at both widths; one-wide (the U pipe alone) is slower.
    let at = |w: &str| -> Vec<f64> {
        rows.iter()
            .filter(|r| r["core.width"] == w)
            .map(|r| r["value"].as_f64().unwrap())
            .collect()
    };
    let (one, two) = (at("1"), at("2"));
    assert_eq!(one.len(), two.len());
    assert!(!one.is_empty());
    assert!(one.iter().zip(&two).all(|(a, b)| a > b), "{one:?} {two:?}");
    assert!(dir.join("sweep.png").exists());
    let again = json(&rtsim(&args));
    assert_eq!(again["rows"], j["rows"], "deterministic");
    for (bad, says) in [
        (vec!["--report", "mft-table9"], "mft-table9"),
        (vec!["--report", "mbvh-fig4-6"], "no --set"),
        (
            vec!["--report", "mft-table2", "--kernel", "drs-bvh4"],
            "--kernel",
        ),
        (vec!["--report", "mft-table2", "--spp", "4"], "--spp"),
        (
            vec!["--report", "mft-table2", "--metric", "nope"],
            "aabb_tests",
        ),
        (vec!["--quick"], "--report"),
        (vec!["--metric", "cycles"], "--report"),
    ] {
        let mut a = vec!["sweep", "--vary", "core.width=1,2"];
        if bad.contains(&"--report") {
            a.extend(["--quick", "--res", "64", "--tiles", "1"]);
        }
        a.extend(bad.iter().copied());
        let e = err(&rtsim(&a));
        assert!(e.contains(says), "{bad:?}: {e}");
    }
}

#[test]
fn replay_runs_every_kernels_windows_on_the_host_and_the_model() {
    if !std::arch::is_x86_feature_detected!("avx2") || !std::arch::is_x86_feature_detected!("fma") {
        eprintln!("skipped: the replayed AVX2 windows need AVX2 + FMA");
        return;
    }
    let j = json(&rtsim(&[
        "replay",
        "--paper",
        "drs",
        "--isa",
        "avx2",
        "--windows",
        "1",
        "--min-ops",
        "100",
        "--max-ops",
        "300",
        "--repeat",
        "2",
        "--machine",
        "zen3",
        "--format",
        "json",
    ]));
    assert_eq!(j["report"], "replay");
    let rows = j["rows"].as_array().unwrap();
    let windows = |k: &str| {
        rows.iter()
            .find(|r| r["metric"] == "windows" && r["kernel"] == k)
            .and_then(|r| r["value"].as_f64())
    };
    // Every DRS kernel on 8 lanes: a window from each of its six traces
    // (two scenes, three streams).
    for k in [
        "single-bvh2",
        "single-bvh4",
        "packet-bvh2",
        "packet-bvh4",
        "hybrid-bvh4",
        "drs-bvh2",
        "drs-bvh4",
    ] {
        assert_eq!(windows(&format!("drs/{k}")), Some(6.0), "{k}");
    }
    assert_eq!(windows("all"), Some(42.0));
    let cpi = |m: &str| {
        rows.iter()
            .find(|r| r["metric"] == m && r["kernel"] == "all")
            .unwrap()["value"]
            .as_f64()
            .unwrap()
    };
    assert!(
        cpi("host_cycles_per_instruction") > 0.05 && cpi("model_cycles_per_instruction") > 0.05
    );
    let e = err(&rtsim(&["replay", "--windows", "0", "--machine", "zen3"]));
    assert!(e.contains("--windows"), "{e}");
    let e = err(&rtsim(&["replay", "--paper", "nope", "--machine", "zen3"]));
    assert!(e.contains("--paper nope"), "{e}");
}
