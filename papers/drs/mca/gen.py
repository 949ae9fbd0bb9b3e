#!/usr/bin/env python3
"""Write bvh2_loop.s: the pipelined DRS BVH2 core loop (closest hit) as the
paper's Appendix A listing, two
iterations per loop body so the current and next ray registers alternate
without moves. Instruction for instruction the op stream rtsim records for
`drs_kernels::pipeline::core_loop` with the BVH2 test, except where x86
needs otherwise (each difference is marked `# x86:`)."""

L = ["0x1000", "0x2000", "0x3000"]   # list bases (absolute, as displacement)
TRAV = "0x100000"                    # ray records
out = [".intel_syntax noprefix", ".text", ".globl drs_bvh2_loop", "drs_bvh2_loop:", "# LLVM-MCA-BEGIN drs-bvh2-core-loop", ".Lloop:"]

def it(cur, nxt, prev_b, d_in, d_out):
    dn, of, ia, ib = cur
    ndn, nof, na, nb = nxt
    e = out.append
    e("  # the previous iteration's last ray: its deferred appends")
    for k, (c, r) in enumerate(zip(d_in, ["rax", "rcx", "rdx"])):
        e(f"  mov word ptr [2*{r} + {L[k]}], {prev_b}w")
        e(f"  and {c}, 1")
        e(f"  add {r}, {c}")
    e("  # read ahead: the next two indices and rays")
    e("  add rsi, 4")
    e(f"  movzx {na}d, word ptr [rsi]")
    e(f"  movzx {nb}d, word ptr [rsi + 2]")
    e(f"  rorx rbx, {na}, 59")
    e(f"  rorx rbp, {nb}, 59")
    e(f"  vmovups ymm4, ymmword ptr [rbx + {TRAV}]")
    e(f"  vmovups ymm5, ymmword ptr [rbp + {TRAV}]")
    e(f"  vperm2f128 {ndn}, ymm4, ymm5, 0x20")
    e(f"  vperm2f128 {nof}, ymm4, ymm5, 0x31")
    e("  # the box test of the current two rays: far planes negated, one max tree")
    e(f"  vxorps ymm6, {of}, ymm14")
    e(f"  vshufps ymm7, {dn}, ymm6, 0xff")
    for a in range(3):
        s = [0x00, 0x55, 0xAA][a]
        dst = ["ymm15", "ymm15", "ymm6"][a]
        e(f"  vpermilps ymm4, {dn}, {s:#x}")
        e(f"  vshufps ymm5, {of}, ymm6, {s:#x}")
        e(f"  vblendvps {dst}, ymm{8 + a}, ymm{11 + a}, ymm4")
        e(f"  vfmsub213ps {dst}, ymm4, ymm5")
        if a == 0:
            e("  vmaxps ymm7, ymm7, ymm15")
    e("  vmaxps ymm15, ymm15, ymm6")
    e("  vmaxps ymm7, ymm7, ymm15")
    e("  # lanes 0-2: left hit, right hit, right nearer; one compare")
    e("  vxorps ymm4, ymm7, ymm14")
    e("  vshufps ymm4, ymm4, ymm7, 0x0e")
    e("  vpermilps ymm5, ymm7, 0x54")
    e("  vcmpleps ymm4, ymm5, ymm4")
    e("  vmovmskps ebx, ymm4")
    e("  # conditions: left-first, right, left-second")
    e("  rorx r13, rbx, 1")
    e("  rorx rbp, rbx, 2")
    e("  and rbp, r13")
    e("  andn r12, rbp, rbx        # x86: andn is rtsim's xor + and")
    e("  and rbp, rbx")
    e("  # the second ray's conditions, kept for the next iteration")
    e(f"  rorx {d_out[0]}, r12, 4")
    e(f"  rorx {d_out[1]}, r13, 4")
    e(f"  rorx {d_out[2]}, rbp, 4")
    e("  # the first ray's appends")
    for k, (c, r) in enumerate(zip(["r12", "r13", "rbp"], ["rax", "rcx", "rdx"])):
        e(f"  mov word ptr [2*{r} + {L[k]}], {ia}w")
        e(f"  and {c}, 1")
        e(f"  add {r}, {c}")
    e("  cmp rsi, rdi")

A = ("ymm0", "ymm1", "r8", "r9")
B = ("ymm2", "ymm3", "r10", "r11")
D = ["r14", "r15", "rbx"]
it(A, B, "r11", D, D)
out.append("  jae .Ldone")
it(B, A, "r9", D, D)
out.append("  jb .Lloop")
out.append("# LLVM-MCA-END")
out.append(".Ldone:")
out.append("  ret")
open(__file__.replace("gen.py", "bvh2_loop.s"), "w").write("\n".join(out) + "\n")
