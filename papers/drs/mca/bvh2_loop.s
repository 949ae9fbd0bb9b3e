.intel_syntax noprefix
.text
.globl drs_bvh2_loop
drs_bvh2_loop:
# LLVM-MCA-BEGIN drs-bvh2-core-loop
.Lloop:
  # the previous iteration's last ray: its deferred appends
  mov word ptr [2*rax + 0x1000], r11w
  and r14, 1
  add rax, r14
  mov word ptr [2*rcx + 0x2000], r11w
  and r15, 1
  add rcx, r15
  mov word ptr [2*rdx + 0x3000], r11w
  and rbx, 1
  add rdx, rbx
  # read ahead: the next two indices and rays
  add rsi, 4
  movzx r10d, word ptr [rsi]
  movzx r11d, word ptr [rsi + 2]
  rorx rbx, r10, 59
  rorx rbp, r11, 59
  vmovups ymm4, ymmword ptr [rbx + 0x100000]
  vmovups ymm5, ymmword ptr [rbp + 0x100000]
  vperm2f128 ymm2, ymm4, ymm5, 0x20
  vperm2f128 ymm3, ymm4, ymm5, 0x31
  # the box test of the current two rays: far planes negated, one max tree
  vxorps ymm6, ymm1, ymm14
  vshufps ymm7, ymm0, ymm6, 0xff
  vpermilps ymm4, ymm0, 0x0
  vshufps ymm5, ymm1, ymm6, 0x0
  vblendvps ymm15, ymm8, ymm11, ymm4
  vfmsub213ps ymm15, ymm4, ymm5
  vmaxps ymm7, ymm7, ymm15
  vpermilps ymm4, ymm0, 0x55
  vshufps ymm5, ymm1, ymm6, 0x55
  vblendvps ymm15, ymm9, ymm12, ymm4
  vfmsub213ps ymm15, ymm4, ymm5
  vpermilps ymm4, ymm0, 0xaa
  vshufps ymm5, ymm1, ymm6, 0xaa
  vblendvps ymm6, ymm10, ymm13, ymm4
  vfmsub213ps ymm6, ymm4, ymm5
  vmaxps ymm15, ymm15, ymm6
  vmaxps ymm7, ymm7, ymm15
  # lanes 0-2: left hit, right hit, right nearer; one compare
  vxorps ymm4, ymm7, ymm14
  vshufps ymm4, ymm4, ymm7, 0x0e
  vpermilps ymm5, ymm7, 0x54
  vcmpleps ymm4, ymm5, ymm4
  vmovmskps ebx, ymm4
  # conditions: left-first, right, left-second
  rorx r13, rbx, 1
  rorx rbp, rbx, 2
  and rbp, r13
  andn r12, rbp, rbx        # x86: andn is rtsim's xor + and
  and rbp, rbx
  # the second ray's conditions, kept for the next iteration
  rorx r14, r12, 4
  rorx r15, r13, 4
  rorx rbx, rbp, 4
  # the first ray's appends
  mov word ptr [2*rax + 0x1000], r8w
  and r12, 1
  add rax, r12
  mov word ptr [2*rcx + 0x2000], r8w
  and r13, 1
  add rcx, r13
  mov word ptr [2*rdx + 0x3000], r8w
  and rbp, 1
  add rdx, rbp
  cmp rsi, rdi
  jae .Ldone
  # the previous iteration's last ray: its deferred appends
  mov word ptr [2*rax + 0x1000], r9w
  and r14, 1
  add rax, r14
  mov word ptr [2*rcx + 0x2000], r9w
  and r15, 1
  add rcx, r15
  mov word ptr [2*rdx + 0x3000], r9w
  and rbx, 1
  add rdx, rbx
  # read ahead: the next two indices and rays
  add rsi, 4
  movzx r8d, word ptr [rsi]
  movzx r9d, word ptr [rsi + 2]
  rorx rbx, r8, 59
  rorx rbp, r9, 59
  vmovups ymm4, ymmword ptr [rbx + 0x100000]
  vmovups ymm5, ymmword ptr [rbp + 0x100000]
  vperm2f128 ymm0, ymm4, ymm5, 0x20
  vperm2f128 ymm1, ymm4, ymm5, 0x31
  # the box test of the current two rays: far planes negated, one max tree
  vxorps ymm6, ymm3, ymm14
  vshufps ymm7, ymm2, ymm6, 0xff
  vpermilps ymm4, ymm2, 0x0
  vshufps ymm5, ymm3, ymm6, 0x0
  vblendvps ymm15, ymm8, ymm11, ymm4
  vfmsub213ps ymm15, ymm4, ymm5
  vmaxps ymm7, ymm7, ymm15
  vpermilps ymm4, ymm2, 0x55
  vshufps ymm5, ymm3, ymm6, 0x55
  vblendvps ymm15, ymm9, ymm12, ymm4
  vfmsub213ps ymm15, ymm4, ymm5
  vpermilps ymm4, ymm2, 0xaa
  vshufps ymm5, ymm3, ymm6, 0xaa
  vblendvps ymm6, ymm10, ymm13, ymm4
  vfmsub213ps ymm6, ymm4, ymm5
  vmaxps ymm15, ymm15, ymm6
  vmaxps ymm7, ymm7, ymm15
  # lanes 0-2: left hit, right hit, right nearer; one compare
  vxorps ymm4, ymm7, ymm14
  vshufps ymm4, ymm4, ymm7, 0x0e
  vpermilps ymm5, ymm7, 0x54
  vcmpleps ymm4, ymm5, ymm4
  vmovmskps ebx, ymm4
  # conditions: left-first, right, left-second
  rorx r13, rbx, 1
  rorx rbp, rbx, 2
  and rbp, r13
  andn r12, rbp, rbx        # x86: andn is rtsim's xor + and
  and rbp, rbx
  # the second ray's conditions, kept for the next iteration
  rorx r14, r12, 4
  rorx r15, r13, 4
  rorx rbx, rbp, 4
  # the first ray's appends
  mov word ptr [2*rax + 0x1000], r10w
  and r12, 1
  add rax, r12
  mov word ptr [2*rcx + 0x2000], r10w
  and r13, 1
  add rcx, r13
  mov word ptr [2*rdx + 0x3000], r10w
  and rbp, 1
  add rdx, rbp
  cmp rsi, rdi
  jb .Lloop
# LLVM-MCA-END
.Ldone:
  ret
