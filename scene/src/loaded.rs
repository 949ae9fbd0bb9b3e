//! A scene stand-in loaded with its BVH2 and the BVH4 collapsed from it:
//! what a report or a kernel test needs before it traces, made in one place.

use crate::bvh::{BuildConfig, Bvh2, Bvh4};

use crate::reference::Reference;
use crate::scene::Scene;

/// A scene and its BVHs.
#[derive(Clone)]
pub struct Loaded {
    /// The scene.
    pub scene: Scene,
    /// Its BVH2.
    pub b2: Bvh2,
    /// The BVH4 collapsed from [`Loaded::b2`].
    pub b4: Bvh4,
}

impl Loaded {
    /// Load scene `name` (built in, a .ron or a mesh file) and build its
    /// BVHs with `cfg`; errors name the file.
    pub fn load(name: &str, cfg: &BuildConfig) -> Result<Loaded, String> {
        let scene = Scene::load(name).map_err(|e| e.0)?;
        let (b2, _) = crate::bvh_cache::build(&scene.mesh, cfg)?;
        let b4 = Bvh4::collapse(&b2);
        Ok(Loaded { scene, b2, b4 })
    }
    /// The f64 reference over the scene's BVH2.
    #[must_use]
    pub fn reference(&self) -> Reference<'_> {
        Reference::with_bvh(&self.scene.mesh, &self.b2)
    }
}
