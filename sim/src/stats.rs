//! Statistics of a simulated run.

use crate::memory::LevelStats;
use isa::{OpClass, Region};

/// Why retirement advanced: each cycle between two retirements is charged to
/// the later op's reason.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(usize)]
pub enum Stall {
    /// Issue bandwidth: the op retired as fast as the front end delivered it.
    Issue = 0,
    /// Waiting for a mispredicted branch to redirect fetch.
    Branch = 1,
    /// A load that overlapped an older store but could not forward from it.
    Forwarding = 2,
    /// A load missed L1 and L2 served it.
    MemoryL2 = 3,
    /// A load missed L1 and L2 and a level below (L3, or an L4 where the
    /// machine has one) served it.
    MemoryL3 = 4,
    /// A load went to DRAM.
    MemoryDram = 5,
    /// Operands: the op waited for the values it reads.
    Dependency = 6,
    /// Port pressure: its operands were ready but its port was busy.
    Ports = 7,
    /// ROB or scheduler full.
    Resources = 8,
    /// The legacy decoders had not delivered the op yet (fetch bytes,
    /// decoder slots, a length-changing prefix).
    FrontEnd = 9,
    /// The core's other hardware thread had the dispatch cycle (SMT).
    Thread = 10,
}

/// Most execution ports a core has (the config checks it).
pub const MAX_PORTS: usize = 16;

impl Stall {
    /// How many reasons there are (the length of the stall arrays).
    pub const COUNT: usize = 11;
    /// All reasons, in the order a CPI stack lists them.
    pub const ALL: [Stall; Stall::COUNT] = [
        Stall::Issue,
        Stall::Branch,
        Stall::Forwarding,
        Stall::MemoryL2,
        Stall::MemoryL3,
        Stall::MemoryDram,
        Stall::Dependency,
        Stall::Ports,
        Stall::Resources,
        Stall::FrontEnd,
        Stall::Thread,
    ];
    /// Stable name.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Stall::Issue => "issue",
            Stall::Branch => "branch",
            Stall::Forwarding => "store-forwarding",
            Stall::MemoryL2 => "memory-l2",
            Stall::MemoryL3 => "memory-l3",
            Stall::MemoryDram => "memory-dram",
            Stall::Dependency => "dependency",
            Stall::Ports => "ports",
            Stall::Resources => "resources",
            Stall::FrontEnd => "front-end",
            Stall::Thread => "other-thread",
        }
    }
    /// The reason for a load served at cache `level` (0: L1, a level
    /// index, or `levels` for DRAM) of a hierarchy of `levels` levels;
    /// `None` for an L1 hit.
    #[inline]
    #[must_use]
    pub fn memory(level: usize, levels: usize) -> Option<Stall> {
        match level {
            0 => None,
            1 if levels > 1 => Some(Stall::MemoryL2),
            l if l >= levels => Some(Stall::MemoryDram),
            _ => Some(Stall::MemoryL3),
        }
    }
}

/// Counters of one simulated run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stats {
    /// Core cycles (for several cores or threads: of the slowest).
    pub cycles: u64,
    /// Instructions: ops, a folded memory operand ([`isa::OpClass::VLoadFold`])
    /// counted as part of the op that reads it.
    pub ops: u64,
    /// Unfused uops executed.
    pub uops: u64,
    /// Instructions per code region (as [`Stats::ops`]).
    pub region_ops: [u64; isa::Region::COUNT],
    /// Cycles charged to each code region (retire-time deltas).
    pub region_cycles: [u64; isa::Region::COUNT],
    /// Ops per class.
    pub class_ops: Vec<u64>,
    /// Cycles charged to each stall reason.
    pub stalls: [u64; Stall::COUNT],
    /// Cycles charged to each stall reason, per code region (out-of-order
    /// cores: each op's retire delta, so a region's row sums to its
    /// `region_cycles`; in-order cores charge waits to no region and leave
    /// this zero).
    pub region_stalls: [[u64; Stall::COUNT]; isa::Region::COUNT],
    /// Of each region's port-pressure cycles ([`Stall::Ports`]), the part
    /// charged to each port: the one its op's longest-waiting uop issued on
    /// (out-of-order cores; a region's row sums to its `Ports` stall).
    pub region_port_stalls: [[u64; MAX_PORTS]; isa::Region::COUNT],
    /// Uops issued to each port, per code region (out-of-order cores).
    pub region_port_uops: [[u64; MAX_PORTS]; isa::Region::COUNT],
    /// Conditional branches.
    pub branches: u64,
    /// Of which mispredicted.
    pub mispredicts: u64,
    /// Vector ops.
    pub vector_ops: u64,
    /// Active lanes summed over vector ops.
    pub active_lanes: u64,
    /// Lanes of the flavour.
    pub lanes: u64,
    /// Loads served by store-to-load forwarding.
    pub forwarded: u64,
    /// Loads that overlapped an older store but could not forward from it.
    pub forward_fails: u64,
    /// Memory-ordering machine clears: a sited load read an older store's
    /// bytes before the store's address was known.
    pub ordering_clears: u64,
    /// Cache level counters.
    pub levels: Vec<LevelStats>,
    /// Cache level names.
    pub level_names: Vec<String>,
    /// DRAM bytes read.
    pub dram_read: u64,
    /// DRAM bytes written.
    pub dram_written: u64,
    /// DRAM bytes read per memory region.
    pub dram_read_by_region: Vec<u64>,
    /// Of those, the bytes the prefetcher read (by the region of the access
    /// that triggered it).
    pub dram_prefetched_by_region: Vec<u64>,
    /// TLB counters (none on a machine without TLBs).
    pub tlb: Option<crate::memory::TlbStats>,
    /// The pipeline timeline of the ops [`crate::SimOptions::timeline`]
    /// asked for (out-of-order cores; empty otherwise).
    pub timeline: Vec<OpTimes>,
}

/// When one op went through the out-of-order pipeline (absolute cycles).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OpTimes {
    /// Its index in the trace.
    pub index: usize,
    /// Its class.
    pub class: OpClass,
    /// Its code region.
    pub region: Region,
    /// Dispatched (renamed into the ROB and scheduler).
    pub dispatch: u64,
    /// Its first uop issued to a port.
    pub issue: u64,
    /// Its result ready (executed).
    pub complete: u64,
    /// Retired.
    pub retire: u64,
    /// What its retire delta was charged to.
    pub stall: Stall,
}

impl Stats {
    /// Empty counters.
    #[must_use]
    pub fn new(lanes: usize) -> Stats {
        Stats {
            class_ops: vec![0; OpClass::ALL.len()],
            lanes: lanes as u64,
            ..Stats::default()
        }
    }
    /// Cycles per instruction.
    #[must_use]
    pub fn cpi(&self) -> f64 {
        self.cycles as f64 / self.ops.max(1) as f64
    }
    /// CPI of one code region (its charged cycles over its ops).
    #[must_use]
    pub fn region_cpi(&self, r: Region) -> Option<f64> {
        let i = r as usize;
        (self.region_ops[i] > 0).then(|| self.region_cycles[i] as f64 / self.region_ops[i] as f64)
    }
    /// Mean active lanes / lanes over vector ops.
    #[must_use]
    pub fn lane_utilisation(&self) -> f64 {
        if self.vector_ops == 0 {
            0.0
        } else {
            self.active_lanes as f64 / (self.vector_ops * self.lanes) as f64
        }
    }
    /// Region `r`'s CPI stack: its cycles per instruction split by stall
    /// reason (in [`Stall::ALL`] order; they sum to its CPI), when its
    /// cycles were charged by reason (out-of-order cores) and it ran.
    #[must_use]
    pub fn cpi_stack(&self, r: Region) -> Option<[f64; Stall::COUNT]> {
        let (i, c) = (r as usize, self.region_stalls[r as usize]);
        let ops = self.region_ops[i];
        (ops > 0 && self.region_cycles[i] > 0 && c.iter().sum::<u64>() == self.region_cycles[i])
            .then(|| c.map(|x| x as f64 / ops as f64))
    }

    /// Region `r`'s port-pressure CPI split by port: per port, the cycles
    /// per instruction its ops waited for that port with their operands
    /// ready (summing to the `ports` entry of [`Stats::cpi_stack`]), when
    /// the region has a CPI stack.
    #[must_use]
    pub fn port_stack(&self, r: Region) -> Option<[f64; MAX_PORTS]> {
        self.cpi_stack(r)?;
        let ops = self.region_ops[r as usize] as f64;
        Some(self.region_port_stalls[r as usize].map(|x| x as f64 / ops))
    }

    /// Region `r`'s uops per cycle on each port (its port pressure), when
    /// it has a CPI stack.
    #[must_use]
    pub fn port_pressure(&self, r: Region) -> Option<[f64; MAX_PORTS]> {
        self.cpi_stack(r)?;
        let cycles = self.region_cycles[r as usize] as f64;
        Some(self.region_port_uops[r as usize].map(|x| x as f64 / cycles))
    }

    /// Region `r`'s largest stall reason other than issue bandwidth (the
    /// base cost of its instructions) and that reason's share of its cycles.
    #[must_use]
    pub fn bottleneck(&self, r: Region) -> Option<(Stall, f64)> {
        let stack = self.cpi_stack(r)?;
        let total: f64 = stack.iter().sum();
        Stall::ALL
            .into_iter()
            .filter(|&s| s != Stall::Issue)
            .map(|s| (s, stack[s as usize] / total))
            .max_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// Add another run's counters (cycles: the maximum).
    pub fn merge(&mut self, o: &Stats) {
        self.cycles = self.cycles.max(o.cycles);
        self.ops += o.ops;
        self.uops += o.uops;
        for i in 0..isa::Region::COUNT {
            self.region_ops[i] += o.region_ops[i];
            self.region_cycles[i] += o.region_cycles[i];
            for (a, b) in self.region_stalls[i].iter_mut().zip(&o.region_stalls[i]) {
                *a += b;
            }
            for p in 0..MAX_PORTS {
                self.region_port_stalls[i][p] += o.region_port_stalls[i][p];
                self.region_port_uops[i][p] += o.region_port_uops[i][p];
            }
        }
        for (a, b) in self.class_ops.iter_mut().zip(&o.class_ops) {
            *a += b;
        }
        for (a, b) in self.stalls.iter_mut().zip(&o.stalls) {
            *a += b;
        }
        self.branches += o.branches;
        self.mispredicts += o.mispredicts;
        self.vector_ops += o.vector_ops;
        self.active_lanes += o.active_lanes;
        self.forwarded += o.forwarded;
        self.forward_fails += o.forward_fails;
        self.ordering_clears += o.ordering_clears;
    }
}

/// Per-ray figures of a run that traced `rays` rays on one core: the one
/// place they are computed. A chip figure assumes every core of the config
/// runs the same work at the simulated core's rate (the papers ran one
/// thread per core over whole frames); `_core` and `_chip` name them apart.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PerRay {
    /// Million rays per second on one core at the config's clock.
    pub mray_per_s_core: f64,
    /// Million rays per second on all the config's cores.
    pub mray_per_s_chip: f64,
    /// Seconds per 10^9 rays on one core.
    pub s_per_gray_core: f64,
    /// Seconds per 10^9 rays on all the config's cores.
    pub s_per_gray_chip: f64,
    /// DRAM bytes (read + written) per ray.
    pub bytes_per_ray: f64,
}

impl PerRay {
    /// From a run's counters.
    #[must_use]
    pub fn new(s: &Stats, rays: u64, clock_ghz: f64, cores: u32) -> PerRay {
        PerRay::of(
            s.cycles,
            s.dram_read + s.dram_written,
            rays,
            clock_ghz,
            cores,
        )
    }
    /// From one core's `cycles` and DRAM bytes for `rays` rays (a rate over
    /// 0 cycles counts 1 cycle, a time over 0 rays counts 1 ray, so an empty
    /// sample gives finite figures).
    #[must_use]
    pub fn of(cycles: u64, dram_bytes: u64, rays: u64, clock_ghz: f64, cores: u32) -> PerRay {
        let hz = clock_ghz * 1e9;
        let per_core = rays as f64 / (cycles.max(1) as f64 / hz) / 1e6;
        let s_core = cycles as f64 / hz / rays.max(1) as f64 * 1e9;
        PerRay {
            mray_per_s_core: per_core,
            mray_per_s_chip: per_core * f64::from(cores),
            s_per_gray_core: s_core,
            s_per_gray_chip: s_core / f64::from(cores),
            bytes_per_ray: dram_bytes as f64 / rays.max(1) as f64,
        }
    }
}

/// 1 if `class` is an instruction of its own, 0 for a folded memory operand.
#[inline(always)]
#[must_use]
pub fn instructions(class: isa::OpClass) -> u64 {
    u64::from(!class.is_folded())
}
