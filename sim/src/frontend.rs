//! The out-of-order core's front end for ops that carry an instruction
//! length: the legacy (x86) decode pipeline, `core.legacy_decode`. Ops
//! without a length come from the uop cache and never reach it.

use crate::config::LegacyDecode;
use isa::Op;

/// The legacy decode pipeline's state: instruction bytes laid out one
/// after another from the trace's first op with a length (a taken branch's
/// target starts a fetch block: loop heads are aligned), one aligned block
/// predecoded per cycle, `decoders` instructions decoded per cycle of which
/// only the first may have several fused uops (Intel's one complex
/// decoder). The predecoder's six instructions per cycle, the instruction
/// queue's and the decoded-uop queue's capacities and the microcode
/// sequencer are not modelled.
pub(crate) struct Legacy {
    cfg: LegacyDecode,
    /// Byte offset of the next instruction.
    pc: u64,
    /// The block predecoded last, and the cycle its instructions are ready.
    block: Option<u64>,
    ready: u64,
    /// The decode cycle of the last instruction, and how many it holds.
    cycle: u64,
    count: u32,
}

impl Legacy {
    pub(crate) fn new(cfg: LegacyDecode) -> Legacy {
        Legacy {
            cfg,
            pc: 0,
            block: None,
            ready: 0,
            cycle: 0,
            count: 0,
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
        let bytes = u64::from(self.cfg.fetch_bytes);
        let end = self.pc + u64::from(op.ilen);
        // Available once the block holding its last byte is predecoded.
        let block = (end - 1) / bytes;
        if self.block != Some(block) {
            let next = self.block.map_or(d, |_| self.ready + 1);
            self.ready = next.max(redirect);
            self.block = Some(block);
        }
        if op.lcp() {
            // The slow length decoder: this block's rest and what follows wait.
            self.ready += u64::from(self.cfg.lcp_penalty);
        }
        if self.ready > self.cycle {
            self.cycle = self.ready;
            self.count = 0;
        }
        if fused > 0 {
            if self.count >= self.cfg.decoders || (fused > 1 && self.count > 0) {
                self.cycle += 1;
                self.count = 0;
            }
            self.count += 1;
        }
        self.pc = if taken {
            end.div_ceil(bytes) * bytes
        } else {
            end
        };
        self.cycle + 1
    }
}
