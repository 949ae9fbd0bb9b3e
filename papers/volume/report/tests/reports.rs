//! The volume paper's Figure 5 computed through the library on a small
//! sample: every timed pixel within the tolerance of the reference, the
//! paper's rows beside ours.

use repro::Given;

#[test]
fn figure_5_checks_every_timed_pixel_and_reports_both_casters() {
    let def = volume_report::REPORTS
        .iter()
        .find(|d| d.name == "volume-fig5")
        .unwrap();
    let dir = std::env::temp_dir().join(format!("volume-fig5-test-{}", std::process::id()));
    let g = Given {
        quick: true,
        tiles: Some(3),
        out: Some(dir.clone()),
        ..Given::default()
    };
    let p = def.compute(g).expect("computed");
    assert_eq!(p.mismatches, 0.0, "pixels differ from the reference");
    // The skull is not shipped (its terms): its row is left out, with a
    // note, unless the data folder has it.
    let skull = scene::scene::data_root()
        .join("volumes/skull_64x64x64_float32le.raw.gz")
        .exists();
    let all = ["engine", "neghip", "skull", "dense"];
    let datasets: Vec<&str> = all.into_iter().filter(|&d| skull || d != "skull").collect();
    assert_eq!(
        p.report
            .notes
            .iter()
            .any(|n| n.contains("skull row is left out")),
        !skull
    );
    assert_eq!(
        p.report.input.as_deref(),
        Some(datasets.join(", ").as_str())
    );
    for &ds in &datasets {
        assert!(
            dir.join(format!("volume-fig5-{ds}.png")).exists(),
            "{ds} image"
        );
    }
    let j = serde_json::to_value(&p.report).unwrap();
    let rows = j["rows"].as_array().unwrap();
    let get = |ds: &str, me: &str, cores: &str| {
        rows.iter()
            .find(|r| {
                r["metric"] == "fps"
                    && r["dataset"] == ds
                    && r["method"] == me
                    && r["cores"] == cores
            })
            .unwrap_or_else(|| panic!("{ds} {me} {cores}"))
    };
    for &ds in &datasets {
        for me in ["gcc", "sse", "bvh"] {
            assert!(get(ds, me, "1")["value"].as_f64().unwrap() > 0.0);
            assert!(
                get(ds, me, "8")["paper"].as_f64().unwrap() > 0.0,
                "the paper's row beside"
            );
        }
        let mac = get(ds, "bvh", "2");
        assert_eq!(mac["machine"], "core2-penryn-2ghz");
        assert!(mac["paper"].as_f64().unwrap() > 0.0);
    }
    // The engine's air is transparent: the BVH skips it.
    let s = rows
        .iter()
        .find(|r| r["metric"] == "speedup_bvh_over_sse" && r["dataset"] == "engine")
        .unwrap();
    assert!(s["value"].as_f64().unwrap() > 1.2, "{s}");
}

#[test]
fn the_bvh_shrinks_by_leaf_size_as_the_paper_says() {
    let def = volume_report::REPORTS
        .iter()
        .find(|d| d.name == "volume-bvh")
        .unwrap();
    let g = Given {
        quick: true,
        tiles: Some(2),
        ..Given::default()
    };
    let p = def.compute(g).expect("computed");
    assert_eq!(p.mismatches, 0.0);
    let j = serde_json::to_value(&p.report).unwrap();
    let ratio = |ds: &str, l: &str| {
        j["rows"]
            .as_array()
            .unwrap()
            .iter()
            .find(|r| {
                r["metric"] == "bvh_bytes_over_volume_bytes" && r["dataset"] == ds && r["leaf"] == l
            })
            .map(|r| r["value"].as_f64().unwrap())
            .unwrap()
    };
    // Each doubling of L shrinks the tree about 8-fold; L = 8 near an eighth
    // of the volume, L = 1 many times it.
    for ds in ["neghip", "engine"] {
        assert!(ratio(ds, "2") > 4.0 * ratio(ds, "4") && ratio(ds, "4") > 4.0 * ratio(ds, "8"));
        assert!((0.05..0.25).contains(&ratio(ds, "8")), "{ds}");
    }
    assert!(ratio("neghip", "1") > 10.0);
}

#[test]
fn table_1_splits_each_column_into_the_papers_stages() {
    let def = volume_report::REPORTS
        .iter()
        .find(|d| d.name == "volume-table1")
        .unwrap();
    let g = Given {
        quick: true,
        tiles: Some(6),
        ..Given::default()
    };
    let p = def.compute(g).expect("computed");
    assert_eq!(p.mismatches, 0.0);
    let j = serde_json::to_value(&p.report).unwrap();
    let rows = j["rows"].as_array().unwrap();
    let pct = |col: &str, stage: &str| {
        rows.iter()
            .find(|r| {
                r["metric"] == "percent_cpu_time" && r["column"] == col && r["stage"] == stage
            })
            .map(|r| r["value"].as_f64().unwrap())
            .unwrap_or_else(|| panic!("{col} {stage}"))
    };
    let stages = volume_report::paper::TABLE1_STAGES;
    for col in [
        "gcc NN",
        "gcc tril",
        "sse NN",
        "sse tril",
        "sse tril BVH diff. phong",
    ] {
        let sum: f64 = stages.iter().map(|s| pct(col, s)).sum();
        assert!((sum - 100.0).abs() < 1e-6, "{col}: {sum}");
        assert!(pct(col, "vox fetch") > 0.0 && pct(col, "classif") > 0.0);
    }
    // Nearest sampling interpolates nothing; only BVH columns traverse; only
    // the Phong column has a highlight.
    assert_eq!(pct("gcc NN", "interp"), 0.0);
    assert_eq!(pct("sse tril", "BVH trav"), 0.0);
    assert!(pct("sse tril BVH", "BVH trav") > 0.0);
    assert_eq!(pct("sse tril BVH diff.", "phong"), 0.0);
    assert!(pct("sse tril BVH diff. phong", "phong") > 0.0);
}

/// The report called `name`.
fn find(name: &str) -> &'static repro::ReportDef {
    volume_report::REPORTS
        .iter()
        .find(|d| d.name == name)
        .unwrap()
}

#[test]
fn figure_6_scales_with_resolution_and_view() {
    let dir = std::env::temp_dir().join(format!("volume-fig6-test-{}", std::process::id()));
    let g = Given {
        quick: true,
        tiles: Some(1),
        out: Some(dir.clone()),
        ..Given::default()
    };
    let p = find("volume-fig6").compute(g).expect("computed");
    assert_eq!(p.mismatches, 0.0);
    let j = serde_json::to_value(&p.report).unwrap();
    let rows = j["rows"].as_array().unwrap();
    for view in ["far", "medium", "close"] {
        assert!(dir
            .join(format!("volume-fig6-mixing256-{view}.png"))
            .exists());
        for me in ["gcc", "sse", "bvh"] {
            let r = rows
                .iter()
                .find(|r| {
                    r["metric"] == "fps"
                        && r["view"] == view
                        && r["method"] == me
                        && r["cores"] == "8"
                })
                .unwrap_or_else(|| panic!("{view} {me}"));
            assert!(r["value"].as_f64().unwrap() > 0.0);
            assert!(r["paper"].as_f64().unwrap() > 0.0, "the paper's 256^3 row");
        }
        // Eq. 7 approximates: the exact traversal is at least as close.
        let psnr = |dsv: &str| {
            rows.iter()
                .find(|r| {
                    r["metric"] == "frame_psnr_vs_reference"
                        && r["view"] == view
                        && r["delta_sv"] == dsv
                })
                .unwrap()["value"]
                .as_f64()
                .unwrap()
        };
        assert!(psnr("0") >= psnr("0.0001"), "{view}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn figure_7_scales_with_the_sampling_rate() {
    let dir = std::env::temp_dir().join(format!("volume-fig7-test-{}", std::process::id()));
    let g = Given {
        quick: true,
        tiles: Some(2),
        out: Some(dir.clone()),
        ..Given::default()
    };
    let p = find("volume-fig7").compute(g).expect("computed");
    for e in -8..=-5 {
        assert!(dir.join(format!("volume-fig7-rda2^{e}.png")).exists());
    }
    assert_eq!(p.mismatches, 0.0);
    let j = serde_json::to_value(&p.report).unwrap();
    let rows = j["rows"].as_array().unwrap();
    let per = |metric: &str| -> Vec<f64> {
        ["2^-8", "2^-7", "2^-6", "2^-5"]
            .iter()
            .map(|e| {
                rows.iter()
                    .find(|r| r["metric"] == metric && r["rda"] == *e && r["cores"] != "8")
                    .unwrap()["value"]
                    .as_f64()
                    .unwrap()
            })
            .collect()
    };
    // Longer steps: fewer samples per voxel and per ray; the first step is
    // chosen for ~2 per voxel at the paper's 2^-7. (The error against
    // uniform sampling falls with rda over the --quick sample's 16 packets,
    // 26.5 to 21.7 dB, but not over these 2: Listing 2's opacity is per
    // sample, so a longer step moves where a ray stops.)
    let density = per("samples_per_voxel");
    let samples = per("reference_samples_per_ray");
    let psnr = per("psnr_vs_uniform_sampling");
    for w in 0..3 {
        assert!(density[w] > density[w + 1], "{density:?}");
        assert!(samples[w] > samples[w + 1], "{samples:?}");
    }
    assert!(psnr.iter().all(|&p| p > 15.0), "{psnr:?}");
    assert!((density[1] - 2.0).abs() < 0.5, "{density:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Report `name` on a pool of `n` host threads, host-measured figures
/// left out.
fn on_threads(n: usize, name: &str, g: Given) -> serde_json::Value {
    volume_report::REPORTS
        .iter()
        .find(|d| d.name == name)
        .unwrap()
        .on_threads(n, g)
        .expect("computed")
}

#[test]
fn one_and_two_host_threads_give_identical_reports() {
    let dir = std::env::temp_dir().join(format!("volume-threads-{}", std::process::id()));
    // Two datasets (the others: the figure's own test).
    let g = || Given {
        quick: true,
        tiles: Some(2),
        out: Some(dir.clone()),
        scenes: vec!["engine".into(), "neghip".into()],
        ..Given::default()
    };
    let one = on_threads(1, "volume-fig5", g());
    assert_eq!(one, on_threads(2, "volume-fig5", g()));
}
