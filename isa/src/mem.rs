//! Memory a kernel touches: registered regions with deterministic simulated
//! addresses (never host pointers), and byte buffers that hold their data.
//!
//! Addresses: regions are placed in registration order from `BASE`, each at a
//! 4 KiB boundary (or its own larger alignment) with a 4 KiB guard gap, so the
//! same registrations always give the same addresses, and the layout and
//! alignment of every structure are what the cache model sees.

use crate::types::{Addr, MemId, MemKind};
use std::marker::PhantomData;
use std::ptr::NonNull;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// Where the first region starts.
pub const BASE: u64 = 0x1000_0000;
/// Region alignment and the gap between regions.
pub const PAGE: u64 = 4096;
/// Size of the ISA layer's own lookup-table region (id 0): the AVX2
/// compress-store permutation table, 256 entries of 8 x u32.
pub const LUT_BYTES: u64 = 256 * 32;

/// One registered region.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MemRegion {
    /// Its id.
    pub id: MemId,
    /// What it holds.
    pub kind: MemKind,
    /// A name a person can read (e.g. `bvh4-nodes`).
    pub name: String,
    /// First byte.
    pub base: Addr,
    /// Size in bytes.
    pub size: u64,
}

impl MemRegion {
    /// Whether `a` lies inside.
    #[must_use]
    pub fn contains(&self, a: Addr) -> bool {
        a.0 >= self.base.0 && a.0 < self.base.0 + self.size
    }
}

/// A point in an [`AddrSpace`]'s allocation history.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SpaceMark {
    regions: usize,
    next: u64,
}

/// The simulated address space of one run.
#[derive(Clone, Debug)]
pub struct AddrSpace {
    regions: Vec<MemRegion>,
    next: u64,
}

impl Default for AddrSpace {
    fn default() -> Self {
        Self::new()
    }
}

/// `n` words as little-endian bytes in a buffer's padded storage
/// ([`padded`]), and their length (collecting a `flat_map` grows the vector
/// step by step: slow for the scenes' hundreds of megabytes).
fn le_bytes(words: impl Iterator<Item = [u8; 4]>, n: usize) -> (Vec<u8>, usize) {
    // Zeroed first, then each word into its 4 bytes: a loop the compiler
    // vectorises (pushing 4 bytes at a time checks the capacity per word).
    let mut bytes = storage(4 * n);
    for (c, w) in bytes.as_chunks_mut::<4>().0.iter_mut().zip(words) {
        *c = w;
    }
    (bytes, 4 * n)
}

/// Bytes every buffer holds past its end: the widest single access (32
/// lanes of 4 bytes), so an access starting at or before the end stays
/// inside the allocation ([`Buf::hot_off`]).
pub const PAD: usize = 128;

/// Zeroed storage for a buffer of `len` bytes and [`PAD`] more.
fn storage(len: usize) -> Vec<u8> {
    vec![0u8; len + PAD]
}

/// `bytes` as a buffer's storage: [`PAD`] zeros more (in place when the
/// vector has room).
fn padded(mut bytes: Vec<u8>) -> Vec<u8> {
    bytes.resize(bytes.len() + PAD, 0);
    bytes
}

impl AddrSpace {
    /// A new space holding only the ISA lookup-table region (id 0).
    #[must_use]
    pub fn new() -> Self {
        let mut s = AddrSpace {
            regions: Vec::new(),
            next: BASE,
        };
        s.place(MemKind::Lut, "isa-lut", LUT_BYTES, 64);
        s
    }

    /// A space with exactly these regions (from a trace header).
    #[must_use]
    pub fn from_regions(regions: Vec<MemRegion>) -> Self {
        let next = regions
            .iter()
            .map(|r| r.base.0 + r.size)
            .max()
            .unwrap_or(BASE);
        AddrSpace { regions, next }
    }

    fn place(&mut self, kind: MemKind, name: &str, size: u64, align: u64) -> MemRegion {
        assert!(
            align.is_power_of_two(),
            "alignment {align} is not a power of two"
        );
        assert!(self.regions.len() < u16::MAX as usize, "too many regions");
        let a = align.max(PAGE);
        let base = self.next.div_ceil(a) * a;
        self.next = base + size.max(1).div_ceil(PAGE) * PAGE + PAGE;
        let r = MemRegion {
            id: MemId(self.regions.len() as u16),
            kind,
            name: name.to_string(),
            base: Addr(base),
            size,
        };
        self.regions.push(r.clone());
        r
    }

    /// A point to roll the space back to with [`AddrSpace::release`].
    #[must_use]
    pub fn mark(&self) -> SpaceMark {
        SpaceMark {
            regions: self.regions.len(),
            next: self.next,
        }
    }

    /// Whether nothing has been placed yet beyond the ISA's own region (as
    /// [`AddrSpace::new`] leaves it).
    #[must_use]
    pub fn is_fresh(&self) -> bool {
        let fresh = AddrSpace::new();
        self.regions.len() == fresh.regions.len() && self.next == fresh.next
    }

    /// Forget every region registered after `mark` (their buffers must not be
    /// used again), e.g. a benchmark iteration's ray buffers.
    pub fn release(&mut self, mark: SpaceMark) {
        assert!(mark.regions <= self.regions.len(), "a mark of this space");
        self.regions.truncate(mark.regions);
        self.next = mark.next;
    }

    /// Leave `bytes` of address space unused (no region, no host memory): e.g.
    /// so that units run by different simulated threads get their own
    /// addresses for buffers they allocate alike.
    pub fn skip(&mut self, bytes: u64) {
        self.next += bytes.div_ceil(PAGE) * PAGE;
    }

    /// Register a zero-filled region of `size` bytes at `align` (power of two).
    pub fn alloc(&mut self, kind: MemKind, name: &str, size: usize, align: usize) -> Buf {
        let r = self.place(kind, name, size as u64, align as u64);
        Buf::new(storage(size), size, r.base, r.id)
    }

    /// Register a region holding `bytes`.
    pub fn alloc_bytes(&mut self, kind: MemKind, name: &str, bytes: Vec<u8>, align: usize) -> Buf {
        let len = bytes.len();
        self.alloc_padded(kind, name, (padded(bytes), len), align)
    }

    /// Register a region of `len` bytes held in `storage(len)`.
    fn alloc_padded(
        &mut self,
        kind: MemKind,
        name: &str,
        (bytes, len): (Vec<u8>, usize),
        align: usize,
    ) -> Buf {
        let r = self.place(kind, name, len as u64, align as u64);
        Buf::new(bytes, len, r.base, r.id)
    }

    /// Register a region holding these f32 values (little-endian).
    pub fn alloc_f32(&mut self, kind: MemKind, name: &str, v: &[f32], align: usize) -> Buf {
        let bytes = le_bytes(v.iter().map(|x| x.to_le_bytes()), v.len());
        self.alloc_padded(kind, name, bytes, align)
    }

    /// Register a region holding these u32 values (little-endian).
    pub fn alloc_u32(&mut self, kind: MemKind, name: &str, v: &[u32], align: usize) -> Buf {
        let bytes = le_bytes(v.iter().map(|x| x.to_le_bytes()), v.len());
        self.alloc_padded(kind, name, bytes, align)
    }

    /// A buffer over the ISA lookup-table region (id 0). Its contents are not
    /// modelled (the expansions compute their results directly), only its addresses.
    #[must_use]
    pub fn lut(&self) -> Buf {
        let r = &self.regions[0];
        let len = r.size as usize;
        Buf::new(storage(len), len, r.base, r.id)
    }

    /// Every region, by id.
    #[must_use]
    pub fn regions(&self) -> &[MemRegion] {
        &self.regions
    }

    /// The region holding `a`, if any.
    #[must_use]
    pub fn find(&self, a: Addr) -> Option<&MemRegion> {
        self.regions.iter().find(|r| r.contains(a))
    }
}

/// The bytes of one registered region. Host-side reads and writes through
/// these methods are not recorded (they are setup and result extraction);
/// kernels access a `Buf` only through the machine's ops. A clone shares the
/// bytes until either writes (copy on write): two machines laying out the
/// same scene (a traced and a warming one) hold it once.
#[derive(Debug)]
pub struct Buf {
    data: Arc<Vec<u8>>,
    /// This `Buf` is the only owner of `data`: set when a write made it so,
    /// cleared by every clone (the only way a second owner appears: a `Buf`
    /// never hands its `Arc` out). A write then needs no atomic
    /// uniqueness check (`Arc::make_mut` costs a locked compare-exchange
    /// per store, 2-4% of a DRS report's host time).
    owned: AtomicBool,
    /// `data`'s bytes and length, read without going through the `Arc` and
    /// the `Vec` (two dependent loads per access, which every byte store
    /// forced the compiler to repeat: a `u8` store may alias them). The
    /// `Vec` is never resized, so these stay valid while `data` lives;
    /// a copy on write moves them to the copy.
    ptr: NonNull<u8>,
    /// The region's size: `data` holds [`PAD`] bytes more.
    len: usize,
    base: Addr,
    id: MemId,
}

// SAFETY: `ptr` points into the `Arc<Vec<u8>>` this `Buf` holds, which is
// Send and Sync; writes through it need `&mut self` and an unshared `Arc`
// (`owned`), as writes through the `Arc` itself would.
unsafe impl Send for Buf {}
// SAFETY: as above; `&self` only reads.
unsafe impl Sync for Buf {}

impl Clone for Buf {
    fn clone(&self) -> Buf {
        self.owned.store(false, Ordering::Relaxed);
        Buf {
            data: Arc::clone(&self.data),
            owned: AtomicBool::new(false),
            ptr: self.ptr,
            len: self.len,
            base: self.base,
            id: self.id,
        }
    }
}

impl Buf {
    /// A buffer of `len` bytes owning `bytes` ([`storage`]`(len)`).
    fn new(bytes: Vec<u8>, len: usize, base: Addr, id: MemId) -> Buf {
        assert_eq!(bytes.len(), len + PAD, "padded storage");
        let mut data = Arc::new(bytes);
        Buf {
            ptr: Self::view(&mut data),
            data,
            owned: AtomicBool::new(true),
            len,
            base,
            id,
        }
    }

    /// Where `data`'s bytes are.
    fn view(data: &mut Arc<Vec<u8>>) -> NonNull<u8> {
        let v = Arc::as_ptr(data);
        // SAFETY: `v` points at the live Vec inside the Arc; its buffer
        // pointer is non-null (the storage is never empty).
        unsafe { NonNull::new_unchecked((*v).as_ptr().cast_mut()) }
    }

    /// Simulated address of byte `off`.
    #[inline(always)]
    #[must_use]
    pub fn addr(&self, off: usize) -> Addr {
        Addr(self.base.0 + off as u64)
    }
    /// The region id.
    #[inline(always)]
    #[must_use]
    pub fn id(&self) -> MemId {
        self.id
    }
    /// Size in bytes.
    #[must_use]
    pub fn len(&self) -> usize {
        self.len
    }
    /// Whether empty.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// All bytes.
    #[must_use]
    pub fn bytes(&self) -> &[u8] {
        &self.data[..self.len]
    }
    /// All bytes, writable.
    pub fn bytes_mut(&mut self) -> &mut [u8] {
        let len = self.len;
        &mut self.data_mut()[..len]
    }

    /// The bytes, writable: copied first if another `Buf` shares them.
    #[inline(always)]
    fn data_mut(&mut self) -> &mut Vec<u8> {
        self.own();
        // SAFETY: `owned` is set only right after `make_mut` left this Arc
        // the allocation's only strong reference (no `Weak` is ever made),
        // and every clone of this `Buf` clears it first, so while it is set
        // no other reference to the bytes exists; `&mut self` excludes any
        // through this `Buf`. This is `Arc::get_mut` without its atomic
        // check (`Arc::as_ptr` points into the Arc's own allocation).
        unsafe { &mut *Arc::as_ptr(&self.data).cast_mut() }
    }

    /// Make the bytes this `Buf`'s alone (a copy if another shares them),
    /// `ptr` pointing at them.
    #[inline(always)]
    fn own(&mut self) {
        if !*self.owned.get_mut() {
            self.take_ownership();
        }
    }

    #[cold]
    #[inline(never)]
    fn take_ownership(&mut self) {
        Arc::make_mut(&mut self.data);
        self.ptr = Self::view(&mut self.data);
        *self.owned.get_mut() = true;
    }

    #[inline(always)]
    fn check(&self, off: usize, n: usize) {
        if off.checked_add(n).is_none_or(|e| e > self.len) {
            out_of_bounds(self.id, off, n, self.len);
        }
    }

    /// A kernel or host access's offset of `n` bytes by `how`.
    #[inline(always)]
    fn at(&self, off: usize, n: usize, how: Bounds) -> usize {
        match how {
            Bounds::Checked => {
                self.check(off, n);
                off
            }
            Bounds::Hot => self.hot_off(off, n),
        }
    }

    /// `B` bytes at `off`, its offset by `how`.
    #[inline(always)]
    fn read_by<const B: usize>(&self, off: usize, how: Bounds) -> [u8; B] {
        let off = self.at(off, B, how);
        let mut r = [0u8; B];
        // SAFETY: `at` keeps `off + B` within the storage `ptr` points at
        // (inside the region when checked; within its PAD bytes past the
        // end when only its start is, B <= PAD then).
        unsafe { std::ptr::copy_nonoverlapping(self.ptr.as_ptr().add(off), r.as_mut_ptr(), B) };
        r
    }

    /// Write `B` bytes at `off`, its offset by `how`.
    #[inline(always)]
    fn write_by<const B: usize>(&mut self, off: usize, b: [u8; B], how: Bounds) {
        let off = self.at(off, B, how);
        self.own();
        // SAFETY: as `read_by`; the bytes are this `Buf`'s alone.
        unsafe { std::ptr::copy_nonoverlapping(b.as_ptr(), self.ptr.as_ptr().add(off), B) };
    }

    /// `N` f32 lanes at `off` (one load), its offset by `how`.
    #[inline(always)]
    fn f32s_by<const N: usize>(&self, off: usize, how: Bounds) -> [f32; N] {
        let off = self.at(off, 4 * N, how);
        #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
        if N == 8 {
            // SAFETY: as `read_by`; one unaligned 32-byte load.
            unsafe {
                use std::arch::x86_64::*;
                let v = _mm256_loadu_ps(self.ptr.as_ptr().add(off) as *const f32);
                return std::mem::transmute_copy::<__m256, [f32; N]>(&v);
            }
        }
        let mut r = [0f32; N];
        // SAFETY: as `read_by`; unaligned read of plain bytes.
        unsafe {
            std::ptr::copy_nonoverlapping(
                self.ptr.as_ptr().add(off),
                r.as_mut_ptr() as *mut u8,
                4 * N,
            );
        }
        #[cfg(target_endian = "big")]
        for x in &mut r {
            *x = f32::from_bits(x.to_bits().swap_bytes());
        }
        r
    }

    /// Write `N` f32 lanes at `off` (one store), its offset by `how`.
    #[inline(always)]
    fn set_f32s_by<const N: usize>(&mut self, off: usize, v: &[f32; N], how: Bounds) {
        let off = self.at(off, 4 * N, how);
        #[cfg(target_endian = "big")]
        let v = &v.map(|x| f32::from_bits(x.to_bits().swap_bytes()));
        self.own();
        // SAFETY: as `read_by`; unaligned write of plain bytes this `Buf`
        // alone holds.
        unsafe {
            std::ptr::copy_nonoverlapping(
                v.as_ptr() as *const u8,
                self.ptr.as_ptr().add(off),
                4 * N,
            );
        }
    }

    /// An unsigned little-endian integer of `width` bytes (1, 2, 4 or 8),
    /// its offset by `how`.
    #[inline(always)]
    fn uint_by(&self, off: usize, width: usize, how: Bounds) -> u64 {
        match width {
            1 => u64::from(self.read_by::<1>(off, how)[0]),
            2 => u64::from(u16::from_le_bytes(self.read_by(off, how))),
            4 => u64::from(u32::from_le_bytes(self.read_by(off, how))),
            8 => u64::from_le_bytes(self.read_by(off, how)),
            _ => panic!("integer width {width} is not 1, 2, 4 or 8"),
        }
    }

    /// Write the low `width` bytes of `v` little-endian, its offset by `how`.
    #[inline(always)]
    fn set_uint_by(&mut self, off: usize, width: usize, v: u64, how: Bounds) {
        match width {
            1 => self.write_by(off, [v as u8], how),
            2 => self.write_by(off, (v as u16).to_le_bytes(), how),
            4 => self.write_by(off, (v as u32).to_le_bytes(), how),
            8 => self.write_by(off, v.to_le_bytes(), how),
            _ => panic!("integer width {width} is not 1, 2, 4 or 8"),
        }
    }

    /// Read `N` bytes at `off`.
    #[inline(always)]
    #[must_use]
    pub fn read<const B: usize>(&self, off: usize) -> [u8; B] {
        self.read_by(off, Bounds::Checked)
    }
    /// Write bytes at `off`.
    #[inline(always)]
    pub fn write(&mut self, off: usize, b: &[u8]) {
        self.check(off, b.len());
        self.own();
        // SAFETY: bounds checked above; the bytes are this `Buf`'s alone.
        unsafe { std::ptr::copy_nonoverlapping(b.as_ptr(), self.ptr.as_ptr().add(off), b.len()) };
    }
    /// Read an f32 at `off`.
    #[inline(always)]
    #[must_use]
    pub fn f32_at(&self, off: usize) -> f32 {
        f32::from_le_bytes(self.read::<4>(off))
    }
    /// Write an f32 at `off`.
    #[inline(always)]
    pub fn set_f32(&mut self, off: usize, v: f32) {
        self.write_by(off, v.to_le_bytes(), Bounds::Checked);
    }
    /// Read a u32 at `off`.
    #[inline(always)]
    #[must_use]
    pub fn u32_at(&self, off: usize) -> u32 {
        u32::from_le_bytes(self.read::<4>(off))
    }
    /// Write a u32 at `off`.
    #[inline(always)]
    pub fn set_u32(&mut self, off: usize, v: u32) {
        self.write_by(off, v.to_le_bytes(), Bounds::Checked);
    }
    /// Read a u16 at `off`.
    #[inline(always)]
    #[must_use]
    pub fn u16_at(&self, off: usize) -> u16 {
        u16::from_le_bytes(self.read::<2>(off))
    }
    /// Write a u16 at `off`.
    #[inline(always)]
    pub fn set_u16(&mut self, off: usize, v: u16) {
        self.write_by(off, v.to_le_bytes(), Bounds::Checked);
    }
    /// Read `N` f32 lanes at `off`.
    #[inline(always)]
    #[must_use]
    pub fn f32s<const N: usize>(&self, off: usize) -> [f32; N] {
        self.f32s_by(off, Bounds::Checked)
    }
    /// Write `N` f32 lanes at `off`.
    #[inline(always)]
    pub fn set_f32s<const N: usize>(&mut self, off: usize, v: &[f32; N]) {
        self.set_f32s_by(off, v, Bounds::Checked);
    }
    /// Read an unsigned little-endian integer of `width` bytes (1, 2, 4 or 8).
    #[inline(always)]
    #[must_use]
    pub fn uint_at(&self, off: usize, width: usize) -> u64 {
        self.uint_by(off, width, Bounds::Checked)
    }
    /// Write the low `width` bytes of `v` little-endian.
    #[inline(always)]
    pub fn set_uint(&mut self, off: usize, width: usize, v: u64) {
        self.set_uint_by(off, width, v, Bounds::Checked);
    }

    /// The offset a kernel's access of `n` bytes (at most [`PAD`]) at `off`
    /// uses on the native backend's hot path: checked in debug builds (an
    /// access outside the region panics naming it, as every other access
    /// does); in release builds only its start against the buffer's end (the
    /// rest of the check hoisted to the buffer's allocation, which holds
    /// [`PAD`] bytes past its end): one compare and a branch predicted not
    /// taken, which the address does not wait for, where a clamp's
    /// conditional move was on its chain. Memory-safe either way.
    #[inline(always)]
    #[must_use]
    pub fn hot_off(&self, off: usize, n: usize) -> usize {
        debug_assert!(n <= PAD, "a hot access of {n} bytes");
        hot_bound(self.id, off, n, self.len);
        off
    }
    /// [`Buf::f32_at`] by [`Buf::hot_off`].
    #[inline(always)]
    #[must_use]
    pub fn hot_f32(&self, off: usize) -> f32 {
        f32::from_le_bytes(self.read_by(off, Bounds::Hot))
    }
    /// [`Buf::set_f32`] by [`Buf::hot_off`].
    #[inline(always)]
    pub fn hot_set_f32(&mut self, off: usize, v: f32) {
        self.write_by(off, v.to_le_bytes(), Bounds::Hot);
    }
    /// [`Buf::f32s`] by [`Buf::hot_off`].
    #[inline(always)]
    #[must_use]
    pub fn hot_f32s<const N: usize>(&self, off: usize) -> [f32; N] {
        const { assert!(4 * N <= PAD) };
        self.f32s_by(off, Bounds::Hot)
    }
    /// [`Buf::set_f32s`] by [`Buf::hot_off`].
    #[inline(always)]
    pub fn hot_set_f32s<const N: usize>(&mut self, off: usize, v: &[f32; N]) {
        const { assert!(4 * N <= PAD) };
        self.set_f32s_by(off, v, Bounds::Hot);
    }
    /// [`Buf::uint_at`] by [`Buf::hot_off`].
    #[inline(always)]
    #[must_use]
    pub fn hot_uint(&self, off: usize, width: usize) -> u64 {
        self.uint_by(off, width, Bounds::Hot)
    }
    /// [`Buf::set_uint`] by [`Buf::hot_off`].
    #[inline(always)]
    pub fn hot_set_uint(&mut self, off: usize, width: usize, v: u64) {
        self.set_uint_by(off, width, v, Bounds::Hot);
    }
}

/// A buffer opened for a run of stores ([`Buf::open`]): its bytes'
/// pointer, end and id read once and its ownership settled once, so a store
/// is a compare against the end, a branch and the store. Through the
/// `Buf` itself every store retested ownership and reloaded the buffer's
/// fields, since a byte store may alias them: 10 host instructions a list
/// append in the DRS core loop where a hand-written one takes 4. The `Buf`
/// stays mutably borrowed while this lives, so no clone can share its
/// bytes meanwhile.
pub struct OpenBuf<'b> {
    ptr: NonNull<u8>,
    len: usize,
    base: Addr,
    id: MemId,
    buf: PhantomData<&'b mut Buf>,
}

impl Buf {
    /// This buffer opened for a run of stores (its bytes copied first if
    /// another `Buf` shares them).
    #[inline(always)]
    pub fn open(&mut self) -> OpenBuf<'_> {
        self.own();
        OpenBuf {
            ptr: self.ptr,
            len: self.len,
            base: self.base,
            id: self.id,
            buf: PhantomData,
        }
    }
}

impl OpenBuf<'_> {
    /// Simulated address of byte `off`.
    #[inline(always)]
    #[must_use]
    pub fn addr(&self, off: usize) -> Addr {
        Addr(self.base.0 + off as u64)
    }
    /// The region id.
    #[inline(always)]
    #[must_use]
    pub fn id(&self) -> MemId {
        self.id
    }
    /// [`Buf::hot_set_uint`] through the opened view: the low `width`
    /// bytes (1, 2, 4 or 8) of `v` at `off`, little-endian.
    #[inline(always)]
    pub fn hot_set_uint(&mut self, off: usize, width: usize, v: u64) {
        match width {
            1 => self.write([v as u8], off),
            2 => self.write((v as u16).to_le_bytes(), off),
            4 => self.write((v as u32).to_le_bytes(), off),
            8 => self.write(v.to_le_bytes(), off),
            _ => panic!("integer width {width} is not 1, 2, 4 or 8"),
        }
    }
    /// `B` bytes at `off`, bounded as [`Buf::hot_off`] bounds them.
    #[inline(always)]
    fn write<const B: usize>(&mut self, b: [u8; B], off: usize) {
        hot_bound(self.id, off, B, self.len);
        // SAFETY: `off` is at most the region's end and the allocation
        // holds PAD (>= 8) bytes past it (in debug builds the whole access
        // lies inside the region); `Buf::open` made the bytes this view's
        // alone and the `Buf` stays mutably borrowed while it lives.
        unsafe { std::ptr::copy_nonoverlapping(b.as_ptr(), self.ptr.as_ptr().add(off), B) };
    }
}

/// The bound of a native access of `n` bytes at `off` in a region of `len`
/// bytes (its allocation PAD bytes longer): the whole access inside the
/// region in debug builds; in release builds its start at most the end,
/// one compare and a branch predicted not taken, off the address's
/// dependency chain. Past it, the panic naming the region.
#[inline(always)]
fn hot_bound(id: MemId, off: usize, n: usize, len: usize) {
    let outside = if cfg!(debug_assertions) {
        off.checked_add(n).is_none_or(|e| e > len)
    } else {
        off > len
    };
    if outside {
        out_of_bounds(id, off, n, len);
    }
}

/// How an access's offset is bounded: [`Buf::check`]ed (host setup and the
/// traced backend: outside the region panics) or [`Buf::hot_off`] (the
/// native backend's ops). Always a constant where an accessor is inlined.
#[derive(Clone, Copy)]
enum Bounds {
    Checked,
    Hot,
}

/// Out of line so the hot path keeps no panic arguments alive.
#[cold]
#[inline(never)]
fn out_of_bounds(id: MemId, off: usize, n: usize, len: usize) -> ! {
    panic!(
        "access of {n} bytes at offset {off} outside region {} of {len} bytes",
        id.0
    )
}

/// An effective address operand: `base + index * scale + disp` bytes into a
/// buffer, like x86's `[reg + index*scale + disp]` (the buffer's own address
/// is a loop-invariant register, not recorded). Base and index are machine
/// scalars, so a load whose address comes from loaded or computed data
/// depends on the ops that made it.
#[derive(Clone, Copy, Debug)]
pub struct At<S> {
    /// Optional base value, added unscaled (a second address register).
    pub base: Option<S>,
    /// Optional index value.
    pub index: Option<S>,
    /// Index scale: 1, 2, 4 or 8 (x86 addressing modes; free).
    pub scale: u8,
    /// Constant byte displacement.
    pub disp: usize,
}

impl<S> At<S> {
    /// A constant byte offset.
    #[inline(always)]
    pub fn off(disp: usize) -> Self {
        At {
            base: None,
            index: None,
            scale: 1,
            disp,
        }
    }
    /// `index * scale + disp`.
    #[inline(always)]
    pub fn idx(index: S, scale: u8, disp: usize) -> Self {
        debug_assert!(matches!(scale, 1 | 2 | 4 | 8), "scale {scale}");
        At {
            base: None,
            index: Some(index),
            scale,
            disp,
        }
    }
    /// `base + index * scale + disp`: two address registers, as x86's
    /// `[base + index*scale + disp]` (e.g. a node's address plus a child's
    /// lane from a bit scan: the load depends on both).
    #[inline(always)]
    pub fn base_idx(base: S, index: S, scale: u8, disp: usize) -> Self {
        debug_assert!(matches!(scale, 1 | 2 | 4 | 8), "scale {scale}");
        At {
            base: Some(base),
            index: Some(index),
            scale,
            disp,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placement_is_deterministic_and_aligned() {
        let mut a = AddrSpace::new();
        let x = a.alloc(MemKind::Nodes, "nodes", 100, 64);
        let y = a.alloc(MemKind::Rays, "rays", 5000, 8192);
        assert_eq!(x.addr(0).0 % PAGE, 0);
        assert_eq!(y.addr(0).0 % 8192, 0);
        assert!(y.addr(0).0 >= x.addr(100).0 + PAGE);
        let mut b = AddrSpace::new();
        let x2 = b.alloc(MemKind::Nodes, "nodes", 100, 64);
        assert_eq!(x.addr(0), x2.addr(0));
        assert_eq!(a.regions()[0].kind, MemKind::Lut);
        assert_eq!(a.find(y.addr(4999)).map(|r| r.id), Some(y.id()));
        assert!(a.find(y.addr(5000)).is_none());
    }

    #[test]
    fn clones_share_bytes_until_either_writes() {
        let mut s = AddrSpace::new();
        let mut a = s.alloc(MemKind::Other, "a", 64, 64);
        a.set_u32(0, 1);
        let mut b = a.clone();
        assert!(std::ptr::eq(a.bytes().as_ptr(), b.bytes().as_ptr()));
        // The clone writes: it gets its own bytes, the original keeps its.
        b.set_u32(0, 2);
        assert_eq!((a.u32_at(0), b.u32_at(0)), (1, 2));
        // The original, once cloned, copies too; a clone of a clone as well.
        let c = a.clone();
        a.set_f32s(4, &[3.0f32]);
        let mut d = c.clone();
        d.bytes_mut()[8] = 9;
        assert_eq!((a.f32_at(4), c.f32_at(4), d.f32_at(4)), (3.0, 0.0, 0.0));
        assert_eq!((c.bytes()[8], d.bytes()[8], a.bytes()[8]), (0, 9, 0));
        // The last owner writes in place once the others are gone.
        drop((c, d));
        let p = a.bytes().as_ptr();
        a.set_u32(12, 7);
        assert_eq!((a.bytes().as_ptr(), a.u32_at(12)), (p, 7));
    }

    #[test]
    fn an_opened_buffer_stores_as_the_buffer_does_and_copies_a_shared_one_first() {
        let mut s = AddrSpace::new();
        let mut a = s.alloc(MemKind::Other, "a", 64, 64);
        let b = a.clone();
        let mut c = s.alloc(MemKind::Other, "c", 64, 64);
        let stores = [
            (0, 1, 0xAB),
            (2, 2, 0xBEEF),
            (4, 4, 0xDEAD_BEEF),
            (8, 8, u64::MAX - 7),
        ];
        {
            let mut o = a.open();
            assert_eq!((o.id(), o.addr(3)), (b.id(), b.addr(3)));
            for (off, w, v) in stores {
                o.hot_set_uint(off, w, v);
            }
        }
        for (off, w, v) in stores {
            c.set_uint(off, w, v);
        }
        assert_eq!(a.bytes(), c.bytes());
        // The clone kept the bytes both shared before the stores.
        assert!(b.bytes().iter().all(|&x| x == 0));
    }

    #[test]
    #[should_panic(expected = "outside region")]
    fn a_store_past_an_opened_buffers_end_is_caught() {
        let mut s = AddrSpace::new();
        let mut a = s.alloc(MemKind::Other, "a", 16, 64);
        a.open().hot_set_uint(17, 2, 1);
    }

    #[test]
    fn host_access() {
        let mut s = AddrSpace::new();
        let mut b = s.alloc(MemKind::Other, "b", 64, 64);
        b.set_f32s(4, &[1.0f32, 2.0, 3.0]);
        assert_eq!(b.f32s::<3>(4), [1.0, 2.0, 3.0]);
        b.set_uint(20, 2, 0xbeef);
        assert_eq!(b.uint_at(20, 2), 0xbeef);
    }

    #[test]
    #[should_panic(expected = "outside region")]
    fn out_of_bounds_is_caught() {
        let mut s = AddrSpace::new();
        let b = s.alloc(MemKind::Other, "b", 16, 64);
        let _ = b.f32s::<8>(0);
    }

    #[test]
    #[cfg(debug_assertions)]
    #[should_panic(expected = "outside region")]
    fn hot_access_out_of_bounds_is_caught_in_debug_builds() {
        let mut s = AddrSpace::new();
        let b = s.alloc(MemKind::Other, "b", 40, 64);
        assert_eq!(b.hot_f32s::<8>(8), [0.0; 8]);
        let _ = b.hot_f32s::<8>(12);
    }

    #[test]
    #[cfg(not(debug_assertions))]
    fn hot_access_from_the_end_reads_the_padding_in_release_builds() {
        let mut s = AddrSpace::new();
        let mut b = s.alloc(MemKind::Other, "b", 40, 64);
        b.set_u32(36, 7);
        // A start at the end is in bounds: the access reads the padding.
        assert_eq!(b.hot_uint(40, 4), 0);
        assert_eq!(b.hot_f32s::<32>(40), [0.0; 32]);
        assert_eq!(b.hot_uint(36, 4), 7);
    }

    #[test]
    #[cfg(not(debug_assertions))]
    #[should_panic(expected = "outside region")]
    fn hot_access_past_the_end_is_caught_in_release_builds() {
        let mut s = AddrSpace::new();
        let b = s.alloc(MemKind::Other, "b", 40, 64);
        let _ = b.hot_uint(400, 4);
    }

    #[test]
    fn storage_is_padded_past_the_end() {
        let mut s = AddrSpace::new();
        for len in [0, 1, 40, 64, 65, 4096] {
            let b = s.alloc(MemKind::Other, "b", len, 64);
            assert_eq!(b.len(), len);
            assert_eq!(b.bytes().len(), len);
            assert_eq!(b.data.len(), len + PAD);
            let f = s.alloc_f32(MemKind::Other, "f", &vec![1.0; len], 64);
            assert_eq!((f.len(), f.data.len()), (4 * len, 4 * len + PAD));
        }
    }
}
