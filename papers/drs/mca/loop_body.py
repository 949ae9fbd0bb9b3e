#!/usr/bin/env python3
"""Cut one steady-state iteration of a loop out of an rtsim text trace, as a
loop body for `rtsim sim --iterations N`.

    loop_body.py TRACE SITE K > body.txt

Takes the ops between the K-th and (K+1)-th `branch ... site=SITE` lines
(the back edge), and the iteration before it to find what is loop-carried: a
source defined in the previous iteration becomes the value defined at the
same position of the body (a source defined later in the body, which
`rtsim sim --iterations` reads as loop-carried); a source defined before
both (loop-invariant) is dropped, being ready before the loop starts."""
import re
import sys

path, site, k = sys.argv[1], sys.argv[2], int(sys.argv[3])
lines = open(path).read().splitlines()
head = [l for l in lines if l.startswith(".") and not l.startswith(".code")]
backs = [i for i, l in enumerate(lines) if l.startswith("branch") and f"site={site} " in l + " "]
a, b, c = backs[k - 1], backs[k], backs[k + 1]
prev, body = lines[a + 1 : b + 1], lines[b + 1 : c + 1]
assert len(prev) == len(body), "iterations of different lengths"
defs = lambda ops: [re.match(r"%(\d+) =", l).group(1) if re.match(r"%\d+ =", l) else None for l in ops]
dprev, dbody = defs(prev), defs(body)
carried = {p: q for p, q in zip(dprev, dbody) if p}
mine = set(x for x in dbody if x)

def fix(l):
    out = []
    for tok in l.split(" "):
        m = re.fullmatch(r"%(\d+)", tok)
        if m and not l.startswith(tok + " ="):
            v = m.group(1)
            if v in carried:
                tok = "%" + carried[v]
            elif v not in mine:
                continue  # loop-invariant
        out.append(tok)
    return " ".join(out)

print("\n".join(head))
print(".code core-loop")
print("\n".join(fix(l) for l in body))
