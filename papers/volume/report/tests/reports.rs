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
    for ds in ["engine", "neghip", "skull", "dense"] {
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
    for ds in ["engine", "neghip", "skull", "dense"] {
        for me in ["sse", "bvh"] {
            assert!(get(ds, me, "1")["value"].as_f64().unwrap() > 0.0);
            assert!(
                get(ds, me, "8")["paper"].as_f64().unwrap() > 0.0,
                "the paper's row beside"
            );
        }
    }
    // The engine's air is transparent: the BVH skips it.
    let s = rows
        .iter()
        .find(|r| r["metric"] == "speedup_bvh_over_sse" && r["dataset"] == "engine")
        .unwrap();
    assert!(s["value"].as_f64().unwrap() > 1.2, "{s}");
}
