//! The real meshes load with their triangle counts: the ones the project
//! ships in `data/` always, the extra ones of a wider data folder
//! (`RTSIM_DATA`) when it has them.

use scene::mesh::load;

#[test]
fn shipped_meshes_load_with_expected_triangle_counts() {
    let root = scene::scene::data_root().join("meshes");
    for (file, tris) in [
        ("bmw-m6.ply.gz", 792_746),
        ("stanford-bunny.obj.gz", 69_451),
        ("lucy.ply.gz", 99_970),
        ("stanford-dragon/dragon_vrip.ply.gz", 871_414),
    ] {
        let m = load(&root.join(file)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(m.len(), tris, "{file}");
    }
}

#[test]
fn extra_meshes_load_where_the_data_folder_has_them() {
    let root = scene::scene::data_root().join("meshes");
    for (file, tris) in [
        ("stanford-dragon/dragon_vrip_res4.ply.gz", 11_102),
        ("stanford-dragon/dragon_vrip_res2.ply.gz", 202_520),
        ("teapot.obj", 6_320),
        ("turbineblade.ply.gz", 199_034),
    ] {
        let p = root.join(file);
        if !p.exists() {
            eprintln!("skipped: {} not present", p.display());
            continue;
        }
        let m = load(&p).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(m.len(), tris, "{file}");
    }
    let c = root.join("cornell_box.obj");
    if c.exists() {
        let c = load(&c).unwrap();
        assert!(c.len() >= 30, "cornell box: {}", c.len());
    }
}
