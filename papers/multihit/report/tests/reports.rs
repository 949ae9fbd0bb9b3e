//! The multi-hit paper's reports computed through the library on a small
//! sample: every ray's hit list checked against the reference, node culling
//! ahead at N_query = 1, the paper's statements beside ours.

use repro::Given;

fn value(j: &serde_json::Value, want: &[(&str, &str)], metric: &str) -> Option<f64> {
    j["rows"].as_array().unwrap().iter().find_map(|r| {
        (r["metric"] == metric && want.iter().all(|(k, v)| r[*k] == *v))
            .then(|| r["value"].as_f64().unwrap())
    })
}

#[test]
fn the_summary_checks_every_ray_and_culls_ahead_at_one_hit() {
    // The layered scene, the deepest.
    summary_on(&["layers"]);
}

#[test]
#[ignore = "every deep scene: cargo test -p multihit-report -- --ignored"]
fn the_summary_on_every_deep_scene() {
    summary_on(&[]);
}

/// `multihit-summary --quick` on `scenes` (all the deep group's when
/// empty), which take in the layered scene.
fn summary_on(scenes: &[&str]) {
    let dir = std::env::temp_dir().join(format!(
        "multihit-test-{}-{}",
        std::process::id(),
        scenes.len()
    ));
    let def = multihit_report::REPORTS
        .iter()
        .find(|d| d.name == "multihit-summary")
        .expect("registered");
    let g = Given {
        quick: true,
        tiles: Some(2),
        out: Some(dir.clone()),
        scenes: scenes.iter().map(|s| (*s).to_string()).collect(),
        ..Given::default()
    };
    let p = def.compute(g).expect("computed");
    assert_eq!(p.mismatches, 0.0, "hit lists differ from the reference");
    assert!(dir.join("multihit-summary.png").exists());
    let j = serde_json::to_value(&p.report).unwrap();
    // The layered scene: every primary ray crosses up to 64 layers (128
    // triangles down a quad's diagonal), counted over every pixel.
    let layers = |m: &str| value(&j, &[("scene", "layers")], m).unwrap();
    assert_eq!(layers("max_hits_per_ray"), 128.0);
    assert!(layers("mean_hits_per_ray") > 32.0);
    assert_eq!(layers("rays_for_hit_statistics"), 1024.0 * 768.0);
    // Every scene of the quick run is in the deep group.
    for r in j["rows"].as_array().unwrap() {
        if r["metric"] == "mean_hits_per_ray" {
            assert_eq!(r["group"], "deep");
            assert!(r["value"].as_f64().unwrap() >= 4.0, "{r}");
        }
    }
    // N_query at 1, 2, 4 and every 10% of the most hits.
    let queries: Vec<&str> = j["rows"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| r["metric"] == "fraction_of_max_hits" && r["scene"] == "layers")
        .map(|r| r["n_query"].as_str().unwrap())
        .collect();
    assert_eq!(
        queries,
        ["1", "2", "4", "13", "26", "38", "51", "64", "77", "90", "102", "115", "128"]
    );
    // The crossover in N_query and as three fractions, each with its interval.
    let cross = |per: &str, bound: &str| {
        value(
            &j,
            &[("scene", "layers"), ("per", per), ("bound", bound)],
            "crossover",
        )
        .unwrap()
    };
    let at = cross("n_query", "estimate");
    assert!(at > 4.0 && at < 128.0, "layers cross at N = {at}");
    assert!(cross("n_query", "low95") <= at && at <= cross("n_query", "high95"));
    assert_eq!(cross("max_hits", "estimate"), at / 128.0);
    assert_eq!(cross("p95_hits", "estimate"), at / 64.0);
    let speedup = |n: &str| {
        value(
            &j,
            &[("scene", "layers"), ("n_query", n)],
            "speedup_node_culling_over_naive",
        )
        .unwrap()
    };
    assert!(speedup("1") > 2.0, "culling at N = 1: {}", speedup("1"));
    assert!(speedup("128") < speedup("1"), "the gain falls with N_query");
    let row = j["rows"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["metric"] == "mean_speedup_at_n_query_1")
        .unwrap();
    assert_eq!(row["paper"], 2.0);
    // With Embree 3 on the host, every timed ray went through rtcIntersect1 and
    // rtcIntersect8 with the same filters too (counted in the mismatches
    // above), and its native time ratio stands beside ours.
    let embree = value(
        &j,
        &[("scene", "layers"), ("n_query", "1")],
        "embree_native_speedup_node_culling_over_naive",
    );
    assert_eq!(embree.is_some(), embree_peer::available().is_ok());
}

/// Report `name` on a pool of `n` host threads, host-measured figures
/// left out.
fn on_threads(n: usize, name: &str, g: Given) -> serde_json::Value {
    multihit_report::REPORTS
        .iter()
        .find(|d| d.name == name)
        .unwrap()
        .on_threads(n, g)
        .expect("computed")
}

#[test]
fn one_and_two_host_threads_give_identical_reports() {
    let dir = std::env::temp_dir().join(format!("multihit-threads-{}", std::process::id()));
    let g = || Given {
        quick: true,
        tiles: Some(1),
        out: Some(dir.clone()),
        scenes: vec!["layers".into()],
        ..Given::default()
    };
    let one = on_threads(1, "multihit-fig2", g());
    assert_eq!(one, on_threads(2, "multihit-fig2", g()));
}
