//! Which register file each value of a window lives in. A recorded op names
//! its class, not its operands' types, so the file comes from the producer
//! where the class fixes it and from the consumers where it does not (a
//! scalar load feeding an address is a general register; one feeding a
//! vector add is the low lane of a vector register).

use crate::program::File;
use isa::{Op, OpClass, ValId};
use std::collections::HashMap;

/// Trailing sources of a memory op that are data (a store's value, a
/// mask, a gather's index and merge source), not address registers.
#[must_use]
pub fn data_sources(class: OpClass, mask_regs: bool) -> usize {
    match class {
        OpClass::VStore | OpClass::Store => 1,
        OpClass::VLoadMasked if mask_regs => 2,
        OpClass::VLoadMasked => 1,
        OpClass::VStoreMasked | OpClass::VCompress => 2,
        OpClass::VGather | OpClass::VScatter => 3,
        _ => 0,
    }
}

/// The address sources of `op` (empty for an op that is not a memory op).
#[must_use]
pub fn address_sources(op: &Op, mask_regs: bool) -> &[ValId] {
    let s = op.sources();
    if !op.class.is_mem() {
        return &[];
    }
    &s[..s.len().saturating_sub(data_sources(op.class, mask_regs))]
}

/// The file `op` wants its source `j` in, where its form fixes it.
fn wants(op: &Op, j: usize, mask_regs: bool) -> Option<File> {
    use OpClass as C;
    let n = op.sources().len();
    let mask_file = if mask_regs { File::K } else { File::V };
    if op.class.is_mem() {
        let addr = n.saturating_sub(data_sources(op.class, mask_regs));
        if j < addr {
            return Some(File::G);
        }
        return match (op.class, j - addr) {
            (C::VStore | C::Store, _) => None,
            (C::VLoadMasked, 0) | (C::VStoreMasked | C::VCompress, 0) => Some(mask_file),
            (C::VGather | C::VScatter, 1) => Some(mask_file),
            _ => Some(File::V),
        };
    }
    match op.class {
        C::Alu | C::IMul | C::BitCnt | C::Lea3 | C::Cmp => Some(File::G),
        C::Cmov if j == 0 => Some(File::Flags),
        C::Cmov => Some(File::G),
        C::Branch => Some(File::Flags),
        C::KLogic => Some(File::K),
        C::MovMsk | C::KTest => Some(mask_file),
        C::VMaskMov if j == 2 => Some(File::K),
        C::VCvt | C::VBcast | C::Mov => None,
        C::VInsert if j == 1 => None,
        _ => Some(File::V),
    }
}

fn consumers_want(uses: &[(usize, usize)], ops: &[Op], mask_regs: bool) -> Vec<File> {
    uses.iter()
        .filter_map(|&(i, j)| wants(&ops[i], j, mask_regs))
        .collect()
}

/// The file of every value the window defines or reads.
#[must_use]
pub fn infer(ops: &[Op], mask_regs: bool) -> HashMap<ValId, File> {
    let mut uses: HashMap<ValId, Vec<(usize, usize)>> = HashMap::new();
    for (i, o) in ops.iter().enumerate() {
        for (j, &s) in o.sources().iter().enumerate() {
            uses.entry(s).or_default().push((i, j));
        }
    }
    let mut file = HashMap::new();
    for o in ops {
        if !o.dst.is_some() {
            continue;
        }
        let w = uses
            .get(&o.dst)
            .map(|u| consumers_want(u, ops, mask_regs))
            .unwrap_or_default();
        let src = o.sources().first().and_then(|s| file.get(s).copied());
        file.insert(o.dst, produced(o, &w, src, mask_regs));
    }
    for (v, u) in &uses {
        file.entry(*v).or_insert_with(|| {
            let w = consumers_want(u, ops, mask_regs);
            match w.first() {
                Some(File::Flags) => File::G,
                Some(&f) => f,
                None => File::V,
            }
        });
    }
    file
}

/// The file `o`'s result lives in, given what its consumers want and its
/// first source's file.
fn produced(o: &Op, want: &[File], src: Option<File>, mask_regs: bool) -> File {
    use OpClass as C;
    let scalar_use = want.iter().any(|f| matches!(f, File::G | File::Flags));
    match o.class {
        C::Alu | C::IMul | C::BitCnt | C::Lea3 | C::Cmov | C::MovMsk | C::LoadFold => File::G,
        C::Cmp | C::KTest => File::Flags,
        C::KLogic if mask_regs => File::K,
        C::VCmp | C::VICmp if o.mask.0 == 1 && scalar_use => File::Flags,
        C::VCmp | C::VICmp if mask_regs => File::K,
        C::Load if scalar_use => File::G,
        C::VCvt if o.mask.0 == 1 && src == Some(File::G) => File::V,
        C::VCvt if o.mask.0 == 1 && scalar_use => File::G,
        C::Mov => src.unwrap_or(File::G),
        C::Zero => want.first().copied().unwrap_or(File::G),
        _ => File::V,
    }
}
