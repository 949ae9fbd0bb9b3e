//! The volume in simulated memory as the paper lays it out: voxels in
//! bricks of 4^3 (`scene::volume_bvh::Bricked`) with the x, y and z offset
//! tables (Listing 2's `voff_x`, `voff_y`, `voff_z`), and the preintegrated
//! transfer function, 256 x 256 RGBA entries of 16 bytes (its
//! `preIntegrated[flast][fval]`), each in a memory region of its own so the
//! caches see the real access pattern.

use isa::{Buf, Machine, MemKind};
use scene::transfer::Transfer;
use scene::volume_bvh::Bricked;

/// Bytes of one preintegrated entry (RGBA f32).
pub const PRE_BYTES: usize = 16;

/// Bytes of one ray's integration state between BVH leaves: rgba at 0, the
/// next sample `p` at 16, the step `sdt` at 32, the last classified value
/// at 48 (+ pad).
pub const STATE_BYTES: usize = 64;

/// A volume and its transfer function laid out.
#[derive(Clone)]
pub struct VolBufs {
    /// Voxels in bricks (u8).
    pub voxels: Buf,
    /// Offset tables along x, y, z (u32; one entry past the last voxel).
    pub off: [Buf; 3],
    /// The preintegrated table.
    pub pre: Buf,
    /// Voxels along x, y, z.
    pub dims: [u32; 3],
}

/// Lay `b` (a volume of `dims` voxels) and `tf` out in `m`'s memory.
pub fn lay_out<M: Machine>(m: &mut M, b: &Bricked, dims: [u32; 3], tf: &Transfer) -> VolBufs {
    let sp = m.space();
    let voxels = sp.alloc_bytes(MemKind::Volume, "voxels", b.data.clone(), 64);
    let names = ["voff-x", "voff-y", "voff-z"];
    let off = std::array::from_fn(|a| sp.alloc_u32(MemKind::Volume, names[a], &b.off[a], 64));
    let pre: Vec<f32> = tf.pre.iter().flatten().copied().collect();
    let pre = sp.alloc_f32(MemKind::Lut, "preintegrated", &pre, 64);
    VolBufs {
        voxels,
        off,
        pre,
        dims,
    }
}
