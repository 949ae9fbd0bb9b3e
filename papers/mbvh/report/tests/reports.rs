//! The MBVH paper's reports computed through the library on small samples:
//! every ray checked, the paper's statements checked where they are ours to
//! check, the paper's numbers beside ours.

use repro::Given;

/// Report `name` computed with options `g`, as `--format json` prints it.
fn report(name: &str, g: Given) -> serde_json::Value {
    let def = mbvh_report::REPORTS
        .iter()
        .find(|d| d.name == name)
        .expect("registered");
    let p = def.compute(g).expect("computed");
    assert_eq!(p.mismatches, 0.0, "{name}: rays differ from the reference");
    serde_json::to_value(&p.report).unwrap()
}

fn small(out: &std::path::Path) -> Given {
    Given {
        quick: true,
        tiles: Some(1),
        res: Some(128),
        out: Some(out.to_path_buf()),
        ..Given::default()
    }
}

fn value(j: &serde_json::Value, want: &[(&str, &str)], metric: &str) -> Option<f64> {
    j["rows"].as_array().unwrap().iter().find_map(|r| {
        (r["metric"] == metric && want.iter().all(|(k, v)| r[*k] == *v))
            .then(|| r["value"].as_f64().unwrap())
    })
}

#[test]
fn figures_4_to_6_count_every_method_and_stream_rs_fetching_least() {
    let dir = std::env::temp_dir().join(format!("mbvh-fig4-6-test-{}", std::process::id()));
    let j = report("mbvh-fig4-6", small(&dir));
    assert!(dir.join("mbvh-fig4-6.png").exists());
    let fetch = |m: &str, b: &str, rays: &str| {
        value(
            &j,
            &[("method", m), ("bounce", b), ("rays", rays)],
            "box_fetches_per_ray",
        )
    };
    let mut seen = 0;
    for b in 0..=7 {
        let b = b.to_string();
        for rays in ["primary", "reflection", "shadow"] {
            if let (Some(rs), Some(single)) = (fetch("MBVH RS", &b, rays), fetch("MBVH", &b, rays))
            {
                assert!(rs < single, "bounce {b} {rays}: {rs} >= {single}");
                assert!(fetch("packets", &b, rays).is_some());
                seen += 1;
            }
        }
    }
    assert!(seen >= 8, "{seen} cells");
    // The large-packet baseline (every method's hits are checked: the
    // report's hit_mismatches) tests fewer boxes per primary ray than MBVH
    // RS, and the report says by how much.
    let tests = |m: &str| {
        value(
            &j,
            &[("method", m), ("bounce", "0"), ("rays", "primary")],
            "box_tests_per_ray",
        )
        .unwrap()
    };
    assert!(tests("large packets") < tests("MBVH RS"));
    assert!(tests("large packets 256") < tests("MBVH RS"));
    assert_eq!(value(&j, &[], "hit_mismatches"), Some(0.0));
    assert!(j["notes"].to_string().contains("box tests per primary ray"));
    let paper = j["rows"]
        .as_array()
        .unwrap()
        .iter()
        .any(|r| r["paper"].as_f64() == Some(2.0));
    assert!(
        paper,
        "the paper's primitive tests per primary ray beside ours"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn counter_reports_refuse_a_machine() {
    let def = mbvh_report::REPORTS
        .iter()
        .find(|d| d.name == "mbvh-fig7-8")
        .unwrap();
    let e = def
        .resolve(Given {
            machine: Some("larrabee".into()),
            ..Given::default()
        })
        .unwrap_err();
    assert!(e.0.contains("--machine"), "{}", e.0);
}

#[test]
fn counts_are_the_same_on_one_and_two_host_threads() {
    let run = |n: usize| {
        let dir = std::env::temp_dir().join(format!("mbvh-threads-{n}-{}", std::process::id()));
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap();
        let mut j = pool.install(|| {
            report(
                "mbvh-fig4-6",
                Given {
                    tiles: Some(2),
                    ..small(&dir)
                },
            )
        });
        j["host_seconds"] = serde_json::json!(0);
        std::fs::remove_dir_all(&dir).ok();
        j
    };
    assert_eq!(run(1), run(2));
}

#[test]
fn figure_3_times_frames_the_same_on_one_and_two_host_threads() {
    // Figure 3's ten runs (depths, variants, group sizes) run at once.
    let dir = std::env::temp_dir().join(format!("mbvh-fig3-threads-{}", std::process::id()));
    let g = || Given {
        res: Some(64),
        ..small(&dir)
    };
    let def = mbvh_report::REPORTS
        .iter()
        .find(|d| d.name == "mbvh-fig3")
        .unwrap();
    let j = def.on_threads(1, g()).expect("computed");
    assert_eq!(j, def.on_threads(2, g()).expect("computed"));
    std::fs::remove_dir_all(&dir).ok();
    // Every depth timed, and the shortcut measured.
    assert_eq!(j["machine"], "core2-q6600");
    for b in ["1", "2", "3", "4"] {
        let r = value(
            &j,
            &[("bounces", b), ("method", "MBVH RS")],
            "mrays_per_second",
        )
        .unwrap();
        assert!(r > 0.0 && r.is_finite(), "{b}: {r}");
    }
    assert!(value(
        &j,
        &[("bounces", "1")],
        "mrays_per_second_from_deepest_frame"
    )
    .is_some());
    assert!(value(
        &j,
        &[("method", "MBVH RS over unordered")],
        "speedup_of_paper_choice"
    )
    .is_some());
    assert!(j["ops_simulated"].as_u64().unwrap() > 0);
}
