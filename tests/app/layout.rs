//! The layout rules of ARCHITECTURE.md, checked on the source tree: no
//! import cycle between the files of any crate, an app under 1,000 lines,
//! `#![warn(missing_docs)]` in every library crate, branch sites unique
//! and inside their module's block of the plan (`isa::sites`), and code
//! compiled by instruction set in `isa` only (CI's baseline build).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The workspace's crates: (source folder, root file).
fn crates() -> Vec<(PathBuf, PathBuf)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let toml = std::fs::read_to_string(root.join("Cargo.toml")).unwrap();
    let mut out = vec![(root.join("src"), root.join("src/main.rs"))];
    let members = toml
        .split("members = [")
        .nth(1)
        .unwrap()
        .split(']')
        .next()
        .unwrap();
    for m in members
        .split(',')
        .map(|s| s.trim().trim_matches('"'))
        .filter(|s| !s.is_empty())
    {
        let src = root.join(m).join("src");
        out.push((src.clone(), src.join("lib.rs")));
    }
    out
}

/// Module path (`a::b`) of every file of a crate.
fn modules(src: &Path, root: &Path) -> BTreeMap<String, PathBuf> {
    let mut m = BTreeMap::new();
    let mut walk = vec![src.to_path_buf()];
    while let Some(d) = walk.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk.push(p);
            } else if p.extension().is_some_and(|x| x == "rs") {
                let rel = p.strip_prefix(src).unwrap().with_extension("");
                let mut name = rel.to_string_lossy().replace('/', "::");
                if p == root {
                    name = String::new();
                } else if let Some(s) = name.strip_suffix("::mod") {
                    name = s.to_string();
                }
                m.insert(name, p);
            }
        }
    }
    m
}

/// The files a file refers to through `crate::` and `super::` paths, in
/// code and in doc links alike (test modules included: a cycle through a
/// test or a doc link is still a cycle).
fn edges(file: &Path, me: &str, mods: &BTreeMap<String, PathBuf>) -> BTreeSet<String> {
    let text = std::fs::read_to_string(file).unwrap();
    let mut out = BTreeSet::new();
    let parent = me.rsplit_once("::").map_or("", |p| p.0);
    for (prefix, base) in [("crate::", ""), ("super::", parent)] {
        for (i, _) in text.match_indices(prefix) {
            if text[..i].ends_with(|c: char| c.is_alphanumeric() || c == '_') {
                continue;
            }
            let rest = &text[i + prefix.len()..];
            let path: String = rest
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':')
                .collect();
            let mut full = base.to_string();
            let mut best = None;
            for seg in path.split("::").filter(|s| !s.is_empty()) {
                full = if full.is_empty() {
                    seg.into()
                } else {
                    format!("{full}::{seg}")
                };
                if mods.contains_key(&full) {
                    best = Some(full.clone());
                }
            }
            if let Some(b) = best.filter(|b| b != me) {
                out.insert(b);
            }
        }
    }
    out
}

/// A cycle in the graph, if any (depth-first search).
fn cycle(g: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn dfs(
        n: &str,
        g: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, u8>,
        stack: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        state.insert(n.into(), 1);
        stack.push(n.into());
        for m in g.get(n).into_iter().flatten() {
            match state.get(m.as_str()).copied().unwrap_or(0) {
                1 => {
                    let at = stack.iter().position(|s| s == m).unwrap();
                    let mut c = stack[at..].to_vec();
                    c.push(m.clone());
                    return Some(c);
                }
                0 => {
                    if let Some(c) = dfs(m, g, state, stack) {
                        return Some(c);
                    }
                }
                _ => {}
            }
        }
        stack.pop();
        state.insert(n.into(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for n in g.keys() {
        if state.get(n.as_str()).copied().unwrap_or(0) == 0 {
            if let Some(c) = dfs(n, g, &mut state, &mut Vec::new()) {
                return Some(c);
            }
        }
    }
    None
}

#[test]
fn no_file_level_import_cycle_in_any_crate() {
    for (src, root) in crates() {
        let mods = modules(&src, &root);
        let g: BTreeMap<String, BTreeSet<String>> = mods
            .iter()
            .map(|(name, file)| (name.clone(), edges(file, name, &mods)))
            .collect();
        // The crate root declares every module; it is not a dependency.
        let g = g
            .into_iter()
            .map(|(k, v)| (k, v.into_iter().filter(|d| !d.is_empty()).collect()))
            .collect();
        if let Some(c) = cycle(&g) {
            panic!("{}: import cycle {}", src.display(), c.join(" -> "));
        }
    }
}

#[test]
fn only_isa_compiles_code_by_instruction_set() {
    // CI lints and tests isa alone built for baseline x86-64: elsewhere
    // `cfg!` (both arms compiled) or run-time detection.
    for (src, root) in crates() {
        if src.ends_with("isa/src") {
            continue;
        }
        for file in modules(&src, &root).values() {
            let text = std::fs::read_to_string(file).unwrap();
            for (n, line) in text.lines().enumerate() {
                let attr = line.trim_start().starts_with("#[cfg") || line.contains("#![cfg");
                assert!(
                    !(attr && line.contains("target_feature")),
                    "{}:{}: cfg on target_feature outside isa",
                    file.display(),
                    n + 1
                );
            }
        }
    }
}

#[test]
fn the_app_is_thin_and_every_library_warns_on_missing_docs() {
    let (app, _) = &crates()[0];
    let lines: usize = modules(app, &app.join("main.rs"))
        .values()
        .map(|f| std::fs::read_to_string(f).unwrap().lines().count())
        .sum();
    assert!(lines < 1000, "the app has {lines} lines");
    for (_, root) in &crates()[1..] {
        let text = std::fs::read_to_string(root).unwrap();
        assert!(
            text.contains("#![warn(missing_docs)]"),
            "{}",
            root.display()
        );
    }
}

#[test]
fn branch_sites_are_unique_and_inside_their_modules_block() {
    use isa::sites;
    let modules: [(&[isa::Site], sites::SiteBlock); 13] = [
        (&micro::SITES, sites::MICRO),
        (&rt::boxtest::SITES, sites::BOXTEST),
        (&rt::single::site::ALL, sites::SINGLE),
        (&drs_kernels::bvh4::site::ALL, sites::DRS_BVH4),
        (&drs_kernels::bvh2::site::ALL, sites::DRS_BVH2),
        (&rt::packet::site::ALL, sites::PACKET),
        (&mft_kernels::site::ALL, sites::MFT),
        (&mbvh_kernels::stream::site::ALL, sites::MBVH_RS),
        (&mbvh_kernels::single::site::ALL, sites::MBVH_SINGLE),
        (&mbvh_kernels::packet::site::ALL, sites::MBVH_PACKET),
        (&multihit_kernels::site::ALL, sites::MULTIHIT),
        (&volume_kernels::site::ALL, sites::VOLUME),
        (&mbvh_kernels::large_packet::site::ALL, sites::MBVH_LARGE),
    ];
    let mut seen = BTreeSet::new();
    for (all, block) in modules {
        for s in all {
            assert!(
                block.contains(*s),
                "{}: {s:?} outside its block",
                block.owner
            );
            assert!(seen.insert(s.0), "{}: {s:?} used twice", block.owner);
        }
    }
}
