//! Timing encoded loops on this host, BHive's way: the loop run for n and
//! 2n iterations, each many times, the minimum of each kept, and the
//! difference over n taken (so call overhead, the first iterations' cold
//! misses and the drain cancel). Each window runs in a child process, so a
//! fault in a replayed window is a failed window, not a crashed tool.
//! Time is read from the TSC; the core's clock against it is measured by a
//! chain of dependent adds (one cycle each on every x86-64 core).

use crate::encode::Encoded;
use crate::program::BUFFER_BASE;
use std::arch::x86_64::{_mm_lfence, _rdtsc};

/// A loop's time on the host.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HostTime {
    /// TSC ticks per iteration (minimum over the repeats).
    pub ticks_per_iteration: f64,
    /// Iterations of the shorter run.
    pub iterations: u64,
}

fn ticks(f: extern "C" fn(u64), n: u64) -> u64 {
    // SAFETY: lfence and rdtsc have no preconditions on x86-64.
    unsafe {
        _mm_lfence();
        let t0 = _rdtsc();
        _mm_lfence();
        f(n);
        _mm_lfence();
        let t1 = _rdtsc();
        t1 - t0
    }
}

/// Map `len` bytes at `addr` (or anywhere with `addr` 0), zeroed.
fn map(addr: u64, len: usize, prot: i32) -> Option<*mut u8> {
    let flags = libc::MAP_PRIVATE
        | libc::MAP_ANONYMOUS
        | if addr != 0 {
            libc::MAP_FIXED_NOREPLACE
        } else {
            0
        };
    // SAFETY: an anonymous private mapping; MAP_FIXED_NOREPLACE fails
    // rather than replace an existing mapping.
    let p = unsafe { libc::mmap(addr as *mut libc::c_void, len, prot, flags, -1, 0) };
    (p != libc::MAP_FAILED && (addr == 0 || p as u64 == addr)).then_some(p.cast())
}

/// The pipe the child reports on (for its fault handler).
static FAULT_FD: std::sync::atomic::AtomicI32 = std::sync::atomic::AtomicI32::new(-1);

/// The child's SIGSEGV/SIGBUS handler: report the faulting instruction's
/// and the accessed address as (0, rip, addr) and exit.
extern "C" fn on_fault(_sig: i32, info: *mut libc::siginfo_t, ctx: *mut libc::c_void) {
    // SAFETY: called by the kernel with valid siginfo and ucontext
    // pointers; only async-signal-safe calls (write, _exit) follow.
    unsafe {
        let uc = ctx.cast::<libc::ucontext_t>();
        let rip = (*uc).uc_mcontext.gregs[libc::REG_RIP as usize] as u64;
        let addr = (*info).si_addr() as u64;
        let at = CODE_AT.load(std::sync::atomic::Ordering::Relaxed);
        let w = [0u64, rip.wrapping_sub(at).wrapping_add(1), addr];
        libc::write(
            FAULT_FD.load(std::sync::atomic::Ordering::Relaxed),
            w.as_ptr().cast(),
            24,
        );
        libc::_exit(1);
    }
}

fn catch_faults(fd: i32) {
    FAULT_FD.store(fd, std::sync::atomic::Ordering::Relaxed);
    // SAFETY: installing a handler with a zeroed sigaction and its mask
    // emptied; the handler is async-signal-safe.
    unsafe {
        let mut sa: libc::sigaction = std::mem::zeroed();
        sa.sa_sigaction = on_fault as *const () as usize;
        sa.sa_flags = libc::SA_SIGINFO;
        libc::sigemptyset(&mut sa.sa_mask);
        libc::sigaction(libc::SIGSEGV, &sa, std::ptr::null_mut());
        libc::sigaction(libc::SIGBUS, &sa, std::ptr::null_mut());
    }
}

/// The code's start in the child, for fault reports.
static CODE_AT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// Run in this (child) process: map, time, return (t(n), t(2n), n).
fn measure(
    code: &Encoded,
    init: &[(u64, u8)],
    buffer: u64,
    repeats: u32,
    min_ticks: u64,
) -> Option<(u64, u64, u64)> {
    let buf = map(
        BUFFER_BASE,
        buffer as usize,
        libc::PROT_READ | libc::PROT_WRITE,
    )?;
    for &(a, v) in init {
        let off = a.checked_sub(BUFFER_BASE).filter(|&o| o < buffer)?;
        // SAFETY: `off` is inside the `buffer`-byte mapping at `buf`.
        unsafe { *buf.add(off as usize) = v };
    }
    let len = code.bytes.len().div_ceil(4096) * 4096;
    let p = map(0, len, libc::PROT_READ | libc::PROT_WRITE)?;
    // SAFETY: `p` is a fresh writable mapping of `len >= bytes.len()` bytes;
    // it is made executable (and not writable) before it is called, and the
    // code is a complete function (see `encode`) touching only the buffer.
    let f: extern "C" fn(u64) = unsafe {
        std::ptr::copy_nonoverlapping(code.bytes.as_ptr(), p, code.bytes.len());
        if libc::mprotect(p.cast(), len, libc::PROT_READ | libc::PROT_EXEC) != 0 {
            return None;
        }
        std::mem::transmute::<*mut u8, extern "C" fn(u64)>(p)
    };
    CODE_AT.store(p as u64, std::sync::atomic::Ordering::Relaxed);
    let mut n = 16u64;
    while ticks(f, n) < min_ticks && n < 1 << 30 {
        n *= 2;
    }
    let (mut a, mut b) = (u64::MAX, u64::MAX);
    for _ in 0..repeats {
        a = a.min(ticks(f, n));
        b = b.min(ticks(f, 2 * n));
    }
    Some((a, b, n))
}

/// Time `code` (its buffer `buffer` bytes, `init` bytes set in it) in a
/// child process.
///
/// # Errors
/// The child faulted or could not map its memory.
pub fn time(
    code: &Encoded,
    init: &[(u64, u8)],
    buffer: u64,
    repeats: u32,
    min_ticks: u64,
) -> Result<HostTime, String> {
    let mut fds = [0i32; 2];
    // SAFETY: a pipe into a two-element array.
    if unsafe { libc::pipe(fds.as_mut_ptr()) } != 0 {
        return Err("pipe failed".into());
    }
    // SAFETY: the child only maps memory, runs the encoded loop, writes to
    // the pipe and exits with `_exit` (no destructors, no locks taken).
    let pid = unsafe { libc::fork() };
    if pid == 0 {
        catch_faults(fds[1]);
        // Denormals flushed (FTZ) and read as zero (DAZ): their microcode
        // assists are no part of the model, and the replay's values are
        // not the recorded ones.
        // SAFETY: setting MXCSR bits in this child only.
        #[allow(deprecated)]
        unsafe {
            std::arch::x86_64::_mm_setcsr(std::arch::x86_64::_mm_getcsr() | 0x8040);
        }
        let r = measure(code, init, buffer, repeats, min_ticks).unwrap_or((0, 0, 0));
        let w = [r.0, r.1, r.2];
        // SAFETY: writing 24 bytes from a live array; then exit the child.
        unsafe {
            libc::write(fds[1], w.as_ptr().cast(), 24);
            libc::_exit(0);
        }
    }
    let mut buf = [0u64; 3];
    // SAFETY: reading at most 24 bytes into a 24-byte array; waiting for
    // our own child.
    let got = unsafe {
        libc::close(fds[1]);
        let got = libc::read(fds[0], buf.as_mut_ptr().cast(), 24);
        libc::close(fds[0]);
        let mut status = 0;
        libc::waitpid(pid, &mut status, 0);
        got
    };
    if got == 24 && buf[0] == 0 && buf[1] != 0 {
        return Err(format!(
            "the replayed loop faulted at body offset {:#x} on address {:#x}",
            (buf[1] - 1).wrapping_sub(code.body_start as u64),
            buf[2]
        ));
    }
    if got != 24 || buf[2] == 0 {
        return Err("the replayed loop could not be mapped".into());
    }
    let (a, b, n) = (buf[0], buf[1], buf[2]);
    Ok(HostTime {
        ticks_per_iteration: b.saturating_sub(a) as f64 / n as f64,
        iterations: n,
    })
}
