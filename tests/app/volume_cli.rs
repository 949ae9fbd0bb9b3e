//! `rtsim volume`: a user's volume through the volume paper's casters, and
//! bad volume input (wrong size, unknown type, NaN, empty transfer
//! function, nonsense options) as named errors with exit 2 and no PNG.

use crate::common::*;

fn write(name: &str, bytes: &[u8]) -> String {
    let p = tmp(name);
    std::fs::write(&p, bytes).unwrap();
    p.display().to_string()
}

const TF: &str = "(points: [(value: 0.0, rgba: (0.0, 0.0, 0.0, 0.0)), (value: 100.0, rgba: (0.9, 0.5, 0.2, 0.3))])";

/// A 16^3 ball of value 200 in empty space.
fn ball() -> Vec<u8> {
    let n = 16i32;
    (0..n * n * n)
        .map(|i| {
            let (x, y, z) = (i % n - 8, (i / n) % n - 8, i / (n * n) - 8);
            if x * x + y * y + z * z < 36 {
                200
            } else {
                0
            }
        })
        .collect()
}

#[test]
fn a_volume_is_cast_timed_and_checked_against_the_reference() {
    let vol = write("ball_16x16x16_uint8.raw", &ball());
    let tf = write("ball.ron", TF.as_bytes());
    let png = tmp("ball.png");
    let j = json(&rtsim(&[
        "volume",
        "--volume",
        &vol,
        "--transfer",
        &tf,
        "--res",
        "64",
        "--packets",
        "4",
        "--lighting",
        "diffuse",
        "--out",
        &png.display().to_string(),
        "--format",
        "json",
    ]));
    let rows = j["rows"].as_array().unwrap();
    for me in ["gcc", "sse", "bvh"] {
        let fps = rows
            .iter()
            .find(|r| r["metric"] == "fps" && r["method"] == me)
            .unwrap();
        assert!(fps["value"].as_f64().unwrap() > 0.0, "{me}");
        let off = rows
            .iter()
            .find(|r| r["metric"] == "pixels_off_reference" && r["method"] == me)
            .unwrap();
        assert_eq!(off["value"].as_f64().unwrap(), 0.0, "{me}");
    }
    assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
}

#[test]
fn bad_volume_input_is_a_named_error_and_writes_nothing() {
    let tf = write("good.ron", TF.as_bytes());
    let empty_tf = write("empty.ron", b"(points: [])");
    let short = write("short_4x4x4_uint8.raw", &[0; 10]);
    let odd = write("odd_2x2x2_complex64.raw", &[0; 64]);
    let nan: Vec<u8> = [1.0f32, 1.0, 1.0, f32::NAN, 1.0, 1.0, 1.0, 1.0]
        .iter()
        .flat_map(|f| f.to_le_bytes())
        .collect();
    let nan = write("nan_2x2x2_float32le.raw", &nan);
    let good = write("good_16x16x16_uint8.raw", &ball());
    let png = tmp("never.png");
    let out = png.display().to_string();
    for (args, want) in [
        (
            vec!["--volume", &short, "--transfer", &tf],
            "64 bytes; the file has 10",
        ),
        (
            vec!["--volume", &odd, "--transfer", &tf],
            "unknown voxel type 'complex64'",
        ),
        (
            vec!["--volume", &nan, "--transfer", &tf],
            "voxel 3: not a finite number",
        ),
        (
            vec!["--volume", &good, "--transfer", &empty_tf],
            "empty transfer function",
        ),
        (
            vec!["--volume", "missing_8x8x8_uint8.raw", "--transfer", &tf],
            "missing_8x8x8_uint8.raw",
        ),
        (
            vec!["--volume", &good, "--transfer", &tf, "--res", "12"],
            "--res: 12",
        ),
        (
            vec!["--volume", &good, "--transfer", &tf, "--leaf", "3"],
            "--leaf: 3",
        ),
        (
            vec!["--volume", &good, "--transfer", &tf, "--lighting", "neon"],
            "--lighting: 'neon'",
        ),
        (
            vec![
                "--volume",
                &good,
                "--transfer",
                &tf,
                "--machine",
                "larrabee",
            ],
            "4-wide SSE",
        ),
    ] {
        let mut a = vec!["volume", "--out", &out];
        a.extend(args);
        let e = err(&rtsim(&a));
        assert!(e.contains(want), "{a:?}: {e}");
        assert!(!png.exists(), "{a:?} wrote a PNG");
    }
    // The file is named in file errors.
    let e = err(&rtsim(&["volume", "--volume", &short, "--transfer", &tf]));
    assert!(e.contains("short_4x4x4_uint8.raw"), "{e}");
    let e = err(&rtsim(&[
        "volume",
        "--volume",
        &good,
        "--transfer",
        &empty_tf,
    ]));
    assert!(e.contains("empty.ron"), "{e}");
}
