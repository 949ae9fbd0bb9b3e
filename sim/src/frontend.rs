//! The out-of-order core's front end for ops that carry an instruction
//! length: the legacy (x86) decode pipeline, `core.legacy_decode`. Ops
//! without a length come from the uop cache and never reach it.
//!
//! The rules, in pipeline order (sources in the machine configs):
//! - **Predecode**: instruction bytes are laid out one after another from
//!   the trace's first op with a length (a taken branch's target starts a
//!   fetch block: loop heads are aligned); one aligned block a cycle, at
//!   most `predecode_width` instructions of it a cycle (an instruction
//!   belongs to the block of its last byte); a length-changing prefix
//!   stalls the predecoder `lcp_penalty` cycles.
//! - **Instruction queue**: an instruction enters it when predecoded and
//!   leaves when decoded; with `instruction_queue` entries full the
//!   predecoder waits.
//! - **Decode**: up to `decoders` instructions a cycle, in order; an
//!   instruction of several fused uops or a complex-only one only on the
//!   first decoder, and a complex-only one ends the group; an instruction
//!   that can macro-fuse not on the last decoder (`fusible_not_last`); a
//!   branch (or a fused compare-and-branch) ends the group.
//! - **Decoded-uop queue**: decoded uops wait in it for dispatch; with
//!   `decoded_queue` entries (halved per thread when two share the core)
//!   full the decoders wait, so they run ahead of a stalled back end by at
//!   most that many uops.
//!
//! Not modelled: the predecode-to-decode pipeline delay (a constant offset
//! after a redirect), an instruction crossing a block boundary predecoded
//! partly in each block, the microcode sequencer, the uop cache's and the
//! loop stream detector's own rules (recorded kernels carry no lengths:
//! their loops run from the uop cache at the dispatch width).

use crate::config::LegacyDecode;
use isa::{Op, OpClass};

/// The legacy decode pipeline's state for one thread.
pub(crate) struct Legacy {
    cfg: LegacyDecode,
    /// Byte offset of the next instruction.
    pc: u64,
    /// The block predecoded last, the cycle of its current predecode
    /// group and the instructions that group holds.
    block: Option<u64>,
    ready: u64,
    predecoded: u32,
    /// The decode cycle of the last instruction, how many it holds, and
    /// whether its group is closed.
    cycle: u64,
    count: u32,
    closed: bool,
    /// Decode cycles of the last `instruction_queue` instructions (a ring).
    iq: Vec<u64>,
    iq_seq: u64,
    /// Dispatch cycles of the last decoded-queue's worth of fused uops.
    idq: Vec<u64>,
    idq_seq: u64,
}

impl Legacy {
    /// The pipeline of one of `share` threads on the core.
    pub(crate) fn new(cfg: LegacyDecode, share: u32) -> Legacy {
        let idq = (cfg.decoded_queue / share.max(1)).max(1) as usize;
        Legacy {
            cfg,
            pc: 0,
            block: None,
            ready: 0,
            predecoded: 0,
            cycle: 0,
            count: 0,
            closed: false,
            iq: vec![0; cfg.instruction_queue as usize],
            iq_seq: 0,
            idq: vec![0; idq],
            idq_seq: 0,
        }
    }

    /// Decode an instruction of `fused` uops (0: folded into its neighbour,
    /// no decoder of its own); the first cycle its uops may dispatch. `d`
    /// is the core's dispatch cycle (the fetch starts no earlier), `redirect`
    /// the cycle fetch resumes after a mispredict.
    pub(crate) fn decode(
        &mut self,
        op: &Op,
        fused: u32,
        taken: bool,
        (d, redirect): (u64, u64),
    ) -> u64 {
        let end = self.pc + u64::from(op.ilen);
        self.predecode(op, end, (d, redirect));
        if fused > 0 {
            self.take_decoder(op, fused);
        }
        if op.class == OpClass::Branch {
            self.closed = true;
        }
        let n = self.iq.len() as u64;
        self.iq[(self.iq_seq % n) as usize] = self.cycle;
        self.iq_seq += 1;
        let bytes = u64::from(self.cfg.fetch_bytes);
        self.pc = if taken {
            end.div_ceil(bytes) * bytes
        } else {
            end
        };
        self.cycle + 1
    }

    /// The cycle the instruction ending at byte `end` is predecoded into
    /// the instruction queue: its block's turn, a slot of the block's
    /// predecode group, a free queue entry, and the LCP stall.
    fn predecode(&mut self, op: &Op, end: u64, (d, redirect): (u64, u64)) {
        let block = (end - 1) / u64::from(self.cfg.fetch_bytes);
        if self.block != Some(block) {
            let next = self.block.map_or(d, |_| self.ready + 1);
            self.ready = next.max(redirect);
            self.block = Some(block);
            self.predecoded = 0;
        } else if self.predecoded >= self.cfg.predecode_width {
            self.ready += 1;
            self.predecoded = 0;
        }
        // The entry this instruction takes is free once the instruction
        // that held it (a queue's length before) has been decoded.
        let n = self.iq.len() as u64;
        if self.iq_seq >= n {
            let free = self.iq[(self.iq_seq % n) as usize];
            if free > self.ready {
                self.ready = free;
                self.predecoded = 0;
            }
        }
        self.predecoded += 1;
        if op.lcp() {
            // The slow length decoder: this block's rest and what follows wait.
            self.ready += u64::from(self.cfg.lcp_penalty);
        }
    }

    /// Give the instruction a decoder: in the predecoded cycle's group if
    /// its rules and the decoded-uop queue allow, else in a later one.
    fn take_decoder(&mut self, op: &Op, fused: u32) {
        if self.ready > self.cycle {
            self.new_group(self.ready);
        }
        // Room for its uops: the uop a queue's length before must have
        // been dispatched.
        let n = self.idq.len() as u64;
        let last = self.idq_seq + u64::from(fused) - 1;
        if last >= n {
            let free = self.idq[((last - n) % n) as usize];
            if free > self.cycle {
                self.new_group(free);
            }
        }
        let complex = fused > 1 || op.complex();
        let full = self.count >= self.cfg.decoders;
        let last_decoder = self.count + 1 == self.cfg.decoders;
        if self.closed
            || full
            || complex && self.count > 0
            || op.fusible() && self.cfg.fusible_not_last && last_decoder
        {
            self.new_group(self.cycle + 1);
        }
        self.count += 1;
        if op.complex() {
            self.closed = true;
        }
    }

    fn new_group(&mut self, cycle: u64) {
        self.cycle = cycle;
        self.count = 0;
        self.closed = false;
    }

    /// The instruction decoded last dispatched its `fused` uops in cycle
    /// `d`: their decoded-queue entries free then.
    pub(crate) fn dispatched(&mut self, d: u64, fused: u32) {
        let n = self.idq.len() as u64;
        for _ in 0..fused {
            self.idq[(self.idq_seq % n) as usize] = d;
            self.idq_seq += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use isa::Region;

    fn haswell() -> LegacyDecode {
        crate::MachineConfig::load("haswell-i7-4750hq")
            .unwrap()
            .core
            .legacy_decode
            .unwrap()
    }

    /// The decode cycle of each of `n` 8-byte one-uop ops (two a block,
    /// a block a cycle) whose uops all dispatch at cycle 100.
    fn decode_cycles(share: u32, n: usize) -> Vec<u64> {
        let mut l = Legacy::new(haswell(), share);
        let mut op = Op::new(OpClass::Alu, Region::Other);
        op.ilen = 8;
        (0..n)
            .map(|_| {
                let at = l.decode(&op, 1, false, (0, 0)) - 1;
                l.dispatched(100, 1);
                at
            })
            .collect()
    }

    #[test]
    fn the_decoded_queue_is_halved_per_thread_under_smt() {
        // Alone: 56 uops wait for dispatch; the 57th decodes when the first
        // leaves (cycle 100). Two threads: 28 each.
        let alone = decode_cycles(1, 57);
        assert_eq!(alone[55], 27);
        assert_eq!(alone[56], 100);
        let shared = decode_cycles(2, 29);
        assert_eq!(shared[27], 13);
        assert_eq!(shared[28], 100);
    }
}
