//! End-to-end tests of the timing model through the app: calibration within
//! 3% on every shipped machine, loop replay, determinism, config errors.

use crate::common::*;

use std::process::Output;

const MACHINES: [&str; 14] = [
    "haswell-i7-4750hq",
    "haswell-e5-2650v3",
    "larrabee",
    "core2-q6600",
    "core2-penryn-2ghz",
    "nehalem-x5550",
    "nehalem-x5550-dual",
    "nehalem-w5580",
    "dunnington-x7460",
    "zen1",
    "zen3",
    "zen4",
    "zen4-avx512",
    "icelake-sp",
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
            let sse = ["core2", "nehalem", "dunnington"]
                .iter()
                .any(|p| m.starts_with(p));
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
    let a = rtsim(&[
        "run", "--kernel", "boxtest", "--rays", "512", "--format", "json",
    ]);
    let b = rtsim(&[
        "run", "--kernel", "boxtest", "--rays", "512", "--format", "json",
    ]);
    assert_eq!(strip(&a), strip(&b));
    let a = rtsim(&["calibrate", "--machine", "core2-q6600", "--format", "csv"]);
    let b = rtsim(&["calibrate", "--machine", "core2-q6600", "--format", "csv"]);
    assert_eq!(strip(&a), strip(&b));
}

#[test]
fn run_times_the_boxtest_workload() {
    let j = json(&rtsim(&[
        "run", "--kernel", "boxtest", "--rays", "1024", "--format", "json",
    ]));
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
        "--kernel",
        "boxtest",
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

/// `fidelity --frame` rows of `mode` and `metric`.
fn frame_row(j: &serde_json::Value, mode: &str, metric: &str) -> f64 {
    j["rows"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["mode"] == mode && r["metric"] == metric)
        .unwrap_or_else(|| panic!("{mode} {metric}"))["value"]
        .as_f64()
        .unwrap()
}

#[test]
fn fidelity_frame_measures_each_sampling_design_against_full() {
    // Timing every round with no warming window: SMARTS is full detail, and
    // the reports' window design is no warming at all.
    let args = [
        "fidelity",
        "--frame",
        "conference",
        "--window",
        "4x2",
        "--spp",
        "1",
        "--every",
        "1",
        "--warm",
        "0",
        "--format",
        "json",
    ];
    let j = json(&rtsim(&args));
    assert_eq!(j["report"], "fidelity-frame");
    for metric in ["cycles_per_ray", "cpi", "bytes_per_ray", "rays_timed"] {
        assert_eq!(
            frame_row(&j, "smarts", metric),
            frame_row(&j, "full", metric),
            "{metric}"
        );
        assert_eq!(
            frame_row(&j, "window", metric),
            frame_row(&j, "none", metric),
            "{metric}"
        );
    }
    assert_eq!(frame_row(&j, "full", "cycles_per_ray_error"), 0.0);
    assert!(frame_row(&j, "full", "rays_timed") >= 8.0 * 256.0);
    // Without the previous frame the caches start cold: more DRAM traffic.
    assert!(frame_row(&j, "none", "bytes_per_ray") > frame_row(&j, "full", "bytes_per_ray"));
    for mode in ["full", "smarts", "window", "none"] {
        assert_eq!(frame_row(&j, mode, "hit_mismatches"), 0.0, "{mode}");
    }
    // Every 2nd round timed: about half the rays.
    let mut half = args;
    half[8] = "2";
    let h = json(&rtsim(&half));
    let (timed, all) = (
        frame_row(&h, "smarts", "rays_timed"),
        frame_row(&h, "full", "rays_timed"),
    );
    assert!(timed > 0.3 * all && timed < 0.7 * all, "{timed} of {all}");
}

#[test]
fn fidelity_frame_options_are_checked() {
    let e = err(&rtsim(&["fidelity", "--spp", "2"]));
    assert!(e.contains("--spp is only read with --frame"), "{e}");
    let e = err(&rtsim(&[
        "fidelity",
        "--frame",
        "conference",
        "--window",
        "0x3",
    ]));
    assert!(e.contains("--window: '0x3'"), "{e}");
    let e = err(&rtsim(&[
        "fidelity",
        "--frame",
        "conference",
        "--trace",
        "t.rtt",
    ]));
    assert!(e.contains("exclude each other"), "{e}");
    let e = err(&rtsim(&["fidelity", "--frame", "atlantis"]));
    assert!(e.contains("atlantis"), "{e}");
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

fn haswell_src() -> String {
    std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/configs/machines/haswell-i7-4750hq.ron"
    ))
    .unwrap()
}

/// "line N" of the first line of the Haswell config holding `text`.
fn line_of(text: &str) -> String {
    let src = haswell_src();
    let at = src.find(text).unwrap();
    format!("line {}", src[..at].matches('\n').count() + 1)
}

fn bad_config(name: &str, from: &str, to: &str) -> String {
    let src = haswell_src();
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
        e.contains("unknown.ron") && e.contains(&line_of("rob: 192,")) && e.contains("robb"),
        "{e}"
    );
    let e = bad_config("type.ron", "rob: 192,", "rob: \"big\",");
    assert!(
        e.contains("type.ron") && e.contains(&line_of("rob: 192,")),
        "{e}"
    );
    let e = bad_config(
        "ways.ron",
        "size_kib: 32, ways: 8,",
        "size_kib: 32, ways: 0,",
    );
    assert!(
        e.contains("ways.ron")
            && e.contains("caches[0].ways")
            && e.contains(&line_of("size_kib: 32, ways: 8,")),
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
        e.contains("classes.vadd.uops")
            && e.contains("port 9")
            && e.contains(&line_of("\"vadd\": (lat: 3")),
        "{e}"
    );
    let e = bad_config(
        "tage.ron",
        "predictor_bits: 14,",
        "predictor_bits: 14, tage: Some((tables: 4, table_bits: 10, tag_bits: 9, min_history: 90, max_history: 30)),",
    );
    assert!(
        e.contains("tage.ron")
            && e.contains("core.tage")
            && e.contains("min_history < max_history"),
        "{e}"
    );
    let e = bad_config(
        "tagefield.ron",
        "predictor_bits: 14,",
        "predictor_bits: 14, tage: Some((tables: 4, table_bits: 10, tag_bits: 9, min_history: 4, max_histroy: 30)),",
    );
    assert!(
        e.contains("tagefield.ron") && e.contains("max_histroy"),
        "{e}"
    );
    let e = bad_config(
        "fpsched.ron",
        "scheduler: 60,",
        "scheduler: 60, fp_scheduler: Some((ports: [0, 1, 12], entries: 20)),",
    );
    assert!(
        e.contains("fpsched.ron") && e.contains("core.fp_scheduler.ports") && e.contains("port 12"),
        "{e}"
    );
    let e = bad_config("fetch.ron", "fetch_bytes: 16,", "fetch_bytes: 12,");
    assert!(
        e.contains("fetch.ron") && e.contains("core.legacy_decode.fetch_bytes"),
        "{e}"
    );
    let e = bad_config(
        "tport.ron",
        "taken_branch_ports: [6],",
        "taken_branch_ports: [8],",
    );
    assert!(
        e.contains("core.taken_branch_ports") && e.contains("port 8"),
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
    // Each region's CPI stack sums to its CPI and names one bottleneck.
    for region in ["core-loop", "traversal"] {
        let of = |metric: &str| {
            rows.iter()
                .filter(|r| r["metric"] == metric && r["region"] == region)
                .map(|r| r["value"].as_f64().unwrap())
                .collect::<Vec<f64>>()
        };
        let (cpi, stack) = (of("cpi")[0], of("cpi_stack"));
        assert_eq!(
            stack.len(),
            sim::Stall::COUNT,
            "{region}: one entry per reason"
        );
        let sum: f64 = stack.iter().sum();
        assert!(
            (sum - cpi).abs() < 1e-9 * cpi.max(1.0),
            "{region}: {sum} vs {cpi}"
        );
        let share = of("bottleneck_share");
        assert_eq!(share.len(), 1, "{region}");
        assert!(share[0] > 0.0 && share[0] <= 1.0, "{region}: {share:?}");
        // Its port-pressure entry split by Haswell's 8 ports sums to it,
        // and every port's uops per cycle is at most one.
        let ports = rows
            .iter()
            .find(|r| r["metric"] == "cpi_stack" && r["region"] == region && r["reason"] == "ports")
            .and_then(|r| r["value"].as_f64())
            .unwrap();
        let by_port = of("cpi_stack_ports");
        assert_eq!(by_port.len(), 8, "{region}");
        let sum: f64 = by_port.iter().sum();
        assert!((sum - ports).abs() < 1e-9, "{region}: {sum} vs {ports}");
        let pressure = of("port_uops_per_cycle");
        assert_eq!(pressure.len(), 8, "{region}");
        assert!(
            pressure.iter().all(|&u| (0.0..=1.0).contains(&u)),
            "{pressure:?}"
        );
        assert!(pressure.iter().any(|&u| u > 0.0), "{region}");
    }
    // Wider than the paper's 8 lanes: the DRS kernel on Larrabee's 16 and
    // on the 32-lane what-if.
    for (machine, isa) in [("larrabee", "lrb16"), ("zen4", "wide32")] {
        let o = ok(&rtsim(&[
            "run",
            "--kernel",
            "drs-bvh4",
            "--scene",
            "sphere",
            "--machine",
            machine,
            "--set",
            &format!("isa={isa}"),
        ]));
        assert!(o.contains(&format!("isa {isa}")), "{o}");
    }
    let e = err(&rtsim(&["run", "--kernel", "warp-drive"]));
    assert!(e.contains("warp-drive"), "{e}");
}

fn sim_rows(file: &str, body: &str, iterations: &str) -> (f64, f64, String) {
    let f = tmp(file);
    std::fs::write(&f, body).unwrap();
    let j = json(&rtsim(&[
        "sim",
        "--trace",
        f.to_str().unwrap(),
        "--iterations",
        iterations,
        "--format",
        "json",
    ]));
    let row = |m: &str| {
        j["rows"]
            .as_array()
            .unwrap()
            .iter()
            .find(|r| r["metric"] == m && r.get("class").is_none())
            .unwrap()["value"]
            .as_f64()
            .unwrap()
    };
    (
        row("cycles_per_iteration"),
        row("cycles_per_iteration_all"),
        j["notes"].to_string(),
    )
}

#[test]
fn sim_iterations_report_the_loops_steady_state() {
    // A loop whose first iteration walks the page table (20 cycles) and
    // misses to DRAM (196) and whose steady state is the imul chain (3
    // cycles per iteration).
    let body = ".trace 1\n.isa avx2\n.mem 0 lut isa-lut 0x10000000 8192\n\
                .mem 1 other d 0x20000000 4096\n%1 = load @d+0x0:8\n%2 = imul %2 %1\n";
    let (steady, all, notes) = sim_rows("cold.txt", body, "100");
    assert_eq!(steady, 3.0, "steady state");
    // The mean counts the cold miss: the first load issues in cycle 1 and
    // completes at 1 + 20 + 196; 100 imuls follow, 3 cycles each.
    assert_eq!(all, (217.0 + 300.0) / 100.0);
    assert!(notes.contains("Steady:"), "{notes}");
    // One iteration is no steady state, and says so.
    let (one, all1, notes) = sim_rows("cold1.txt", &body.replace("%2 %1", "%1"), "1");
    assert_eq!(one, all1);
    assert!(notes.contains("not a steady state"), "{notes}");
}

#[test]
fn sim_iterations_say_when_the_loop_is_not_yet_steady() {
    // Two independent loads a cycle on Haswell (two load ports): 1.00
    // cycles per iteration once steady. At 200 iterations the run still
    // sits behind its first miss (the window of 200 gives 0.59), and the
    // report says so; at every N it calls steady, it gives 1.00.
    let body = ".trace 1\n.isa avx2\n.mem 0 other d 0x20000000 4096\n\
                %1 = load @d+0x0:8\n%2 = load @d+0x40:8\n";
    let (_, _, notes) = sim_rows("loads200.txt", body, "200");
    assert!(notes.contains("NOT STEADY"), "{notes}");
    assert!(notes.contains("--iterations 400"), "{notes}");
    let mut steady = 0;
    for n in ["1000", "1500", "4000", "10000"] {
        let (per, _, notes) = sim_rows(&format!("loads{n}.txt"), body, n);
        if notes.contains("Steady:") {
            assert_eq!(format!("{per:.2}"), "1.00", "{n} iterations: {notes}");
            steady += 1;
        }
    }
    assert_eq!(steady, 4, "each of these N is long enough");
}

#[test]
fn sim_timeline_shows_each_ops_pipeline_stages() {
    // The imul chain: each imul issues when the one before completes, 3 cycles on.
    let f = tmp("chain.txt");
    std::fs::write(
        &f,
        ".trace 1\n.isa avx2\n.mem 0 lut isa-lut 0x10000000 8192\n\
         .mem 1 other d 0x20000000 4096\n%1 = load @d+0x0:8\n%2 = imul %2 %1\n",
    )
    .unwrap();
    let path = f.to_str().unwrap();
    let args = |fmt: &'static str, win: &'static str| {
        vec![
            "sim",
            "--trace",
            path,
            "--iterations",
            "20",
            "--timeline",
            win,
            "--format",
            fmt,
        ]
    };
    let j = json(&rtsim(&args("json", "20:8")));
    let rows = j["rows"].as_array().unwrap();
    let at = |metric: &str| -> Vec<(u64, f64)> {
        rows.iter()
            .filter(|r| r["metric"] == metric && r["class"] == "imul")
            .map(|r| {
                (
                    r["op"].as_str().unwrap().parse().unwrap(),
                    r["value"].as_f64().unwrap(),
                )
            })
            .collect()
    };
    let (issue, done) = (at("issue"), at("complete"));
    assert_eq!(issue.len(), 4, "ops 20..28 hold four imuls");
    for k in 1..issue.len() {
        assert_eq!(
            issue[k].1,
            done[k - 1].1,
            "imul {} waits for the one before",
            issue[k].0
        );
        assert_eq!(done[k].1 - issue[k].1, 3.0, "imul latency");
    }
    let png = tmp("timeline.png");
    let mut with_png = args("json", "20:8");
    with_png.extend(["--timeline-png", png.to_str().unwrap()]);
    ok(&rtsim(&with_png));
    assert_eq!(&std::fs::read(&png).unwrap()[1..4], b"PNG");
    let text = ok(&rtsim(&args("text", "20:8")));
    let view = text.split("Timeline (cycle 0 =").nth(1).expect("the view");
    let lines: Vec<&str> = view.lines().filter(|l| l.contains(" imul ")).collect();
    assert_eq!(lines.len(), 4, "{view}");
    assert!(
        lines.iter().all(|l| l.contains('D') && l.ends_with('R')),
        "{view}"
    );
    for (bad, says) in [
        ("20", "START:LEN"),
        ("nope:0:4", "unknown region"),
        ("0:0", "LEN"),
        ("99999:4", "ops"),
        ("x:4", "not a count"),
    ] {
        let e = err(&rtsim(&args("json", bad)));
        assert!(e.contains(says), "{bad}: {e}");
    }
    let e = err(&rtsim(&[
        "sim",
        "--trace",
        path,
        "--iterations",
        "2",
        "--fidelity",
        "counts",
        "--timeline",
        "0:4",
    ]));
    assert!(e.contains("full fidelity"), "{e}");
}

#[test]
fn run_on_defaults_sets_drs_beside_single_ray_on_one_scene() {
    // The quick start's job, on a small scene: two kernels, the same rays,
    // their headline figures keyed by kernel, every hit checked.
    let j = json(&rtsim(&[
        "run", "--scene", "sphere", "--tile", "8", "--spp", "2", "--format", "json",
    ]));
    assert_eq!(j["report"], "run-compare");
    let rows = j["rows"].as_array().unwrap();
    for k in ["drs-bvh4", "single-bvh4"] {
        let get = |m: &str| {
            rows.iter()
                .find(|r| r["kernel"] == k && r["metric"] == m)
                .and_then(|r| r["value"].as_f64())
                .unwrap_or_else(|| panic!("{k} {m}"))
        };
        assert!(get("mray_per_s") > 0.0 && get("cpi") > 0.0, "{k}");
        assert!(get("bytes_per_ray") > 0.0, "{k}: cold caches");
        assert_eq!(get("hit_mismatches"), 0.0, "{k}");
    }
    let text = ok(&rtsim(&[
        "run", "--scene", "sphere", "--tile", "8", "--spp", "2",
    ]));
    assert!(
        text.contains("by kernel") && text.contains("single-bvh4"),
        "{text}"
    );
}
