//! The multi-hit reports' scenes and viewpoints. The paper renders eight
//! scenes "from the viewpoints depicted in Figure 1", chosen because their
//! "first-hit visible surfaces hide significant internal complexity"; the
//! scenes are not available and their sizes are not given. Ours: rtsim's
//! scenes seen from viewpoints where a pixel-centre ray at 1024x768 meets
//! at least 4 surfaces on average (the deep group, the reports' scenes),
//! chosen on that count alone before any timing; the scenes of the other
//! papers that fall short stay as a labelled extra group.

/// A camera placed for the report (the scene's own camera otherwise).
#[derive(Clone, Copy, Debug)]
pub(crate) struct View {
    pub(crate) eye: [f32; 3],
    pub(crate) target: [f32; 3],
    /// Vertical field of view in degrees.
    pub(crate) fov: f32,
}

/// Which group a scene belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Group {
    /// At least 4 hits per ray on average: the paper's kind of scene.
    Deep,
    /// Fewer: kept as a labelled extra (full runs only).
    Shallow,
}

impl Group {
    /// The label in the reports' rows.
    pub(crate) fn label(self) -> &'static str {
        match self {
            Group::Deep => "deep",
            Group::Shallow => "shallow (extra)",
        }
    }
}

/// One scene of the reports: a name, the built-in scene, the viewpoint.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Stand {
    pub(crate) name: &'static str,
    pub(crate) scene: &'static str,
    pub(crate) view: Option<View>,
    pub(crate) group: Group,
}

/// A viewpoint: the eye, the point looked at, the vertical field of view.
const fn view(eye: [f32; 3], target: [f32; 3], fov: f32) -> Option<View> {
    Some(View { eye, target, fov })
}

const fn deep(name: &'static str, scene: &'static str, view: Option<View>) -> Stand {
    Stand {
        name,
        scene,
        view,
        group: Group::Deep,
    }
}

const fn shallow(name: &'static str) -> Stand {
    Stand {
        name,
        scene: name,
        view: None,
        group: Group::Shallow,
    }
}

/// Every scene, the deep group first. Mean hits per ray over every pixel
/// (measured; papers/multihit/README.md): truck 4.6, truck-cargo 9.2,
/// truck-interior 13.7, layers 50.5, bmw 4.9, fairy 10.1, courtyard 6.5;
/// conference 1.8, fern 2.8, trex 0.9, saloon 1.6, ferrari 2.0.
pub(crate) const STANDS: [Stand; 12] = [
    // The truck from its front-right corner (its own camera): cab, engine,
    // wheels and the closed cargo body.
    deep("truck", "truck", None),
    // The same truck from behind: the closed cargo body of 400 crates and
    // drums fills the view.
    deep(
        "truck-cargo",
        "truck",
        view([4.0, 3.0, 9.0], [0.0, 2.1, 1.5], 30.0),
    ),
    // Inside the cab above the dashboard, looking back through the seats,
    // the cab's back wall and the cargo body.
    deep(
        "truck-interior",
        "truck",
        view([0.0, 2.4, -3.2], [0.0, 1.8, 3.0], 70.0),
    ),
    deep("layers", "layers", None),
    // pbrt-v3's camera on the BMW M6, its field of view narrowed from 30 to
    // 18 degrees so the car (body, cabin, wheels) fills the frame.
    deep(
        "bmw",
        "bmw",
        view([-11.0, 0.8, 5.0], [-2.0, -0.5, 0.0], 18.0),
    ),
    // Into the Fairy Forest stand-in's trees from the forest's edge.
    deep(
        "fairy",
        "fairy",
        view([0.0, 4.0, 18.0], [0.0, 3.0, 0.0], 25.0),
    ),
    deep("courtyard", "courtyard", None),
    shallow("conference"),
    shallow("fern"),
    shallow("trex"),
    shallow("saloon"),
    shallow("ferrari"),
];

/// Every scene's name, in [`STANDS`]' order (what `--scenes` chooses from).
pub(crate) const NAMES: [&str; STANDS.len()] = repro::names_of!(STANDS);

/// The scenes a run measures: the deep group, and with `extra` the
/// shallow one too; of those, the ones `wanted` takes.
pub(crate) fn chosen(extra: bool, wanted: impl Fn(&str) -> bool) -> Vec<Stand> {
    STANDS
        .iter()
        .copied()
        .filter(|s| (extra || s.group == Group::Deep) && wanted(s.name))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_scenes_are_built_in() {
        for (i, s) in STANDS.iter().enumerate() {
            assert!(STANDS[..i].iter().all(|o| o.name != s.name), "{}", s.name);
            assert!(
                scene::scene::BUILTIN.iter().any(|(n, _)| *n == s.scene),
                "{}",
                s.scene
            );
        }
        assert_eq!(chosen(false, |_| true).len(), 7);
        assert_eq!(chosen(true, |s| s == "layers" || s == "trex").len(), 2);
        assert_eq!(chosen(true, |_| true).len(), STANDS.len());
    }
}
