//! The software-pipelined core loop both DRS kernels share (the paper's
//! Appendix A, section 5): each iteration tests the LANES/4 rays fetched by
//! the one before, and while its box test runs it already fetches the next
//! iteration's ray indices and rays; the last ray's appends wait for the
//! next iteration, so they do not sit behind their own iteration's chain.
//!
//! As in the paper's listing:
//! - one running pointer over the item's 16-bit ray indices, compared with
//!   the item's end (`activeRays < lastActiveRay`);
//! - the first iteration's deferred append stores index 0 with every
//!   condition clear (the paper's `mask = 0`): stores that advance nothing;
//! - the padding duplicate can only be the last iteration's last ray, so
//!   the padding check is out of the loop, on the deferred append after it.
//!
//! The read-ahead after the last iteration reads up to LANES/4 indices past
//! the item's padding. Those entries lie inside the list (each list has 16
//! spare entries per tree level) and hold ray indices of earlier items or
//! zero, so the rays they name are in bounds; their loads are what the
//! hardware would issue too, and their results are never used.

use crate::stream::StreamBufs;
use isa::{At, Buf, Cmp, Machine, Shift, Site};
use rt::boxtest::Pat;

/// One condition per ray pointer list (9 at most; a kernel using fewer
/// leaves the rest unused), fixed-size so the loop allocates nothing.
pub(crate) type Conds<M> = [<M as Machine>::S; 9];

/// `v`'s conditions in a [`Conds`], the rest zero.
pub(crate) fn conds<M: Machine>(m: &mut M, v: &[M::S]) -> Conds<M> {
    let zero = m.int(0);
    std::array::from_fn(|k| v.get(k).copied().unwrap_or(zero))
}

/// Most rays an iteration tests (LANES/4 on 32 lanes).
const MAX_RAYS: usize = 8;

/// One iteration's rays (LANES/4, at most [`MAX_RAYS`]): their indices and
/// records as `[dir, tnear]` and `[org * idir, tfar]` per 4 lanes.
pub(crate) struct Rays<M: Machine> {
    idx: [M::S; MAX_RAYS],
    dir_near: M::F,
    org_far: M::F,
}

/// A ray whose appends are deferred to the next iteration.
struct Deferred<M: Machine> {
    idx: M::S,
    conds: Conds<M>,
}

/// The core loop over an item: `count` ray indices at byte `at` of the
/// lists; `test` takes an iteration's `dir_near`, `org_far` and returns one
/// condition per list (ray q's at bit 4q); `cnt` are the `L` lists' ends,
/// advanced by the appends (a fixed-size array, so natively they stay in
/// registers as the paper's list pointers do). `sites` are the loop's back
/// edge and the padding check.
#[allow(clippy::too_many_arguments)]
pub(crate) fn core_loop<M: Machine, const N: usize>(
    m: &mut M,
    st: &mut StreamBufs,
    trav: &Buf,
    (at, count): (M::S, M::S),
    cnt: &mut [M::S],
    sites: (Site, Site),
    test: impl FnMut(&mut M, M::F, M::F) -> Conds<M>,
) {
    fn fixed<M: Machine, const N: usize, const L: usize>(
        m: &mut M,
        (st, trav): (&mut StreamBufs, &Buf),
        (at, count): (M::S, M::S),
        cnt: &mut [M::S],
        sites: (Site, Site),
        test: impl FnMut(&mut M, M::F, M::F) -> Conds<M>,
    ) {
        let mut c: [M::S; L] = std::array::from_fn(|k| cnt[k]);
        core_loop_n::<M, N, L>(m, st, trav, at, count, &mut c, sites, test);
        cnt.copy_from_slice(&c);
    }
    let bufs = (st, trav);
    match cnt.len() {
        2 => fixed::<M, N, 2>(m, bufs, (at, count), cnt, sites, test),
        3 => fixed::<M, N, 3>(m, bufs, (at, count), cnt, sites, test),
        4 => fixed::<M, N, 4>(m, bufs, (at, count), cnt, sites, test),
        9 => fixed::<M, N, 9>(m, bufs, (at, count), cnt, sites, test),
        n => panic!("{n} ray lists"),
    }
}

/// [`core_loop`] over `L` lists.
#[allow(clippy::too_many_arguments)]
fn core_loop_n<M: Machine, const N: usize, const L: usize>(
    m: &mut M,
    st: &mut StreamBufs,
    trav: &Buf,
    at: M::S,
    count: M::S,
    cnt: &mut [M::S; L],
    (back, pad): (Site, Site),
    mut test: impl FnMut(&mut M, M::F, M::F) -> Conds<M>,
) {
    let r = N / 4;
    let list_bytes = st.cap * 2;
    let out = cnt;
    let mut cnt_reg = *out;
    let cnt = &mut cnt_reg;
    let bytes = m.s_shift(Shift::Shl, count, 1);
    let end = m.s_add(at, bytes);
    let mut p = at;
    let mut next = fetch::<M, N>(m, &st.lists, trav, p);
    let zero = m.int(0);
    let mut deferred = Deferred::<M> {
        idx: zero,
        conds: [zero; 9],
    };
    let mut first = true;
    loop {
        // The previous iteration's last ray (nothing advances on the first).
        append_ray(
            m,
            st,
            list_bytes,
            deferred.idx,
            &deferred.conds,
            cnt,
            !first,
        );
        first = false;
        let cur = next;
        p = m.s_addi(p, 2 * r as i64);
        next = fetch::<M, N>(m, &st.lists, trav, p);
        let conds = test(m, cur.dir_near, cur.org_far);
        for q in 0..r - 1 {
            let c = shifted(m, &conds, q, L);
            append_ray(m, st, list_bytes, cur.idx[q], &c, cnt, true);
        }
        deferred = Deferred {
            idx: cur.idx[r - 1],
            conds: shifted(m, &conds, r - 1, L),
        };
        if !m.branch_if(back, Cmp::Lt, p, end) {
            // The last ray, unless it is the padding copy of the one before.
            if r > 1 {
                let dup = m.s_cmp(Cmp::Eq, cur.idx[r - 1], cur.idx[r - 2]);
                if m.branch(pad, dup) {
                    break;
                }
            }
            append_ray(m, st, list_bytes, deferred.idx, &deferred.conds, cnt, true);
            break;
        }
    }
    *out = cnt_reg;
}

/// The conditions of ray `q` at bit 0 (the first `n` lists).
#[inline(always)]
fn shifted<M: Machine>(m: &mut M, conds: &Conds<M>, q: usize, n: usize) -> Conds<M> {
    let mut c = *conds;
    if q > 0 {
        for x in &mut c[..n] {
            *x = m.s_shift(Shift::Shr, *x, 4 * q as u32);
        }
    }
    c
}

/// The LANES/4 ray indices at byte `p` of `lists` and their traversal
/// records, as `[dir, tnear]` and `[org * idir, tfar]` per 4 lanes.
#[inline(always)]
fn fetch<M: Machine, const N: usize>(m: &mut M, lists: &Buf, trav: &Buf, p: M::S) -> Rays<M> {
    let r = N / 4;
    assert!(r <= MAX_RAYS, "{N} lanes: at most {} rays", MAX_RAYS);
    let (dn, of) = (&Pat::<N>::DIR_NEAR, &Pat::<N>::ORG_FAR);
    let (dn_id, of_id) = (Pat::<N>::DN_ID, Pat::<N>::OF_ID);
    let first = m.s_load(lists, At::idx(p, 1, 0), 2, false);
    let mut idx = [first; MAX_RAYS];
    for (q, x) in idx.iter_mut().enumerate().take(r).skip(1) {
        *x = m.s_load(lists, At::idx(p, 1, 2 * q), 2, false);
    }
    let (dir_near, org_far) = if r > 2 {
        (
            blocks(m, trav, &idx[..r], 0),
            blocks(m, trav, &idx[..r], 16),
        )
    } else if r == 1 {
        let ro = m.s_shift(Shift::Shl, idx[0], 5);
        (
            m.load(trav, At::idx(ro, 1, 0)),
            m.load(trav, At::idx(ro, 1, 16)),
        )
    } else {
        let ra = m.s_shift(Shift::Shl, idx[0], 5);
        let rb = m.s_shift(Shift::Shl, idx[1], 5);
        let a = m.loadu(trav, At::idx(ra, 1, 0));
        let b = m.loadu(trav, At::idx(rb, 1, 0));
        let d = if dn_id { a } else { m.shuffle2(a, b, dn) };
        let o = if of_id { b } else { m.shuffle2(a, b, of) };
        (d, o)
    };
    Rays {
        idx,
        dir_near,
        org_far,
    }
}

/// Wider than AVX2 (an extension: the paper's kernel is 8 lanes wide): the
/// 16 bytes at `off` of each ray's record, ray q's in lanes 4q..4q+4 — a
/// 128-bit load repeated across the lanes per ray, merged under a constant
/// mask (AVX-512's merge-masked `vbroadcastf32x4`, here a load and a select).
#[inline(always)]
fn blocks<M: Machine>(m: &mut M, trav: &Buf, idx: &[M::S], off: usize) -> M::F {
    let ro = m.s_shift(Shift::Shl, idx[0], 5);
    let mut v = m.load_repeat(trav, At::idx(ro, 1, off), 4);
    for (q, &i) in idx.iter().enumerate().skip(1) {
        let ro = m.s_shift(Shift::Shl, i, 5);
        let b = m.load_repeat(trav, At::idx(ro, 1, off), 4);
        let k = m.mask(0xF << (4 * q));
        v = m.select(k, b, v);
    }
    v
}

/// Append one ray index to every list (`L` of them, `list_bytes` apart)
/// with a scalar store (through the lists opened once, as the paper's
/// list pointers sit in registers), advancing list k by bit 0 of `conds[k]`
/// (branch-free). `counted`: a real ray-node test (not the first
/// iteration's empty append).
#[inline(always)]
fn append_ray<M: Machine, const L: usize>(
    m: &mut M,
    st: &mut StreamBufs,
    list_bytes: usize,
    idx: M::S,
    conds: &[M::S],
    cnt: &mut [M::S; L],
    counted: bool,
) {
    if counted {
        st.tests.core_loop += 1;
    }
    let one = m.int(1);
    let mut lists = m.open(&mut st.lists);
    for k in 0..L {
        m.s_store_open(&mut lists, At::idx(cnt[k], 2, k * list_bytes), 2, idx);
        let inc = m.s_and(conds[k], one);
        cnt[k] = m.s_add(cnt[k], inc);
    }
}
