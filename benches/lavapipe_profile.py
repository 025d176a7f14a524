#!/usr/bin/env python3
"""Where lavapipe's time goes in glint's compute shader, counted, not sampled.

This machine's timings drift by up to 1.7x within minutes, so wall-time A/B
runs of the shader cannot separate changes under about 15%. Instruction
counts do not drift: this runs one `glint render --backend gpu` under
callgrind (one lavapipe thread), with llvmpipe printing the shader's
machine code (`GALLIVM_DEBUG=asm`, shader cache off so that it compiles),
and joins callgrind's count per instruction address with that code: the
unnamed (`???`) code with the most instructions is placed on the printed
function at the one load address where every counted address starts an
instruction (llvmpipe prints at most 96 KB of a function; what lies past
that is counted but not classified).

Instructions that run the same number of times form one class: a loop
body's iterations (a node visit, a primitive test) or a once-per-batch
part. The report lists the classes by their share, with the count, their
size in instructions and what kinds of instruction they hold (per-lane
gathers, stack-frame traffic, blends).

Usage (Mesa 25 from the CI fetch, as in `.ci/run`):

    VK_DRIVER_FILES=.../lvp_icd.json LD_LIBRARY_PATH=... \\
        benches/lavapipe_profile.py target/release/glint SCENE [--classes N]

Needs valgrind, and a Mesa whose llvmpipe honours GALLIVM_DEBUG=asm.
"""

import argparse
import collections
import os
import re
import subprocess
import sys
import tempfile


def run(glint, scene, workdir):
    out = os.path.join(workdir, "callgrind.out")
    env = dict(os.environ, GALLIVM_DEBUG="asm", MESA_SHADER_CACHE_DISABLE="1", LP_NUM_THREADS="1")
    cmd = ["valgrind", "--tool=callgrind", "--dump-instr=yes", f"--callgrind-out-file={out}",
           glint, "--threads", "1", "render", "--backend", "gpu", scene,
           # Under callgrind a pass runs about 50x slower than its timeout
           # expects.
           "--pass-timeout", "36000",
           "-o", os.path.join(workdir, "image.png")]
    done = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if done.returncode != 0:
        sys.exit(f"the render failed ({done.returncode}):\n{done.stdout[-2000:]}")
    return out, done.stdout


def printed_functions(log):
    """Each function llvmpipe printed (several per pipeline): its name and
    offset -> instruction text."""
    funcs, code = [], None
    for line in log.splitlines():
        if re.match(r"^[A-Za-z_][\w.]*:$", line):
            code = {}
            funcs.append((line[:-1], code))
            continue
        m = re.match(r"\s*([0-9a-f]+):\s*(.*)", line)
        if code is not None and m:
            code[int(m.group(1), 16)] = m.group(2).strip()
    if not funcs:
        sys.exit("no machine code in the output: does this llvmpipe print GALLIVM_DEBUG=asm?")
    return funcs


def counts(path):
    """The JIT code (object `???`) that ran the most instructions: address
    -> instructions run."""
    objects, names = {}, {}
    per_fn = collections.defaultdict(collections.Counter)
    jit, fn, pos, skip = False, None, 0, False
    for line in open(path):
        # Names are given once, at first use; later lines give the id only.
        m = re.match(r"(c?ob|c?fn)=\((\d+)\)(?: (.*))?", line)
        if m:
            kind, ident, name = m.groups()
            table = objects if kind.endswith("ob") else names
            if name:
                table[ident] = name.strip()
            if kind == "ob":
                jit = objects.get(ident) == "???"
            elif kind == "fn":
                fn = names.get(ident) if jit else None
            continue
        if line.startswith("calls="):
            skip = True
            continue
        if not line or line[0] not in "0123456789+-*":
            continue
        parts = line.split()
        p = parts[0]
        if p.startswith("0x"):
            pos = int(p, 16)
        elif p[0] in "+-":
            pos += int(p, 0)
        elif p != "*":
            pos = int(p, 0)
        if skip:
            skip = False
            continue
        # positions: instr line, then the Ir count.
        if fn and len(parts) > 2:
            per_fn[fn][pos] += int(parts[2])
    if not per_fn:
        sys.exit("callgrind saw no JIT code")
    return max(per_fn.values(), key=lambda c: sum(c.values()))


def locate(funcs, ir):
    """The printed function that ran and its load address: the one base at
    which every counted address starts one of its instructions. callgrind
    names JIT code by the first address it entered, which need not be the
    function's start (a coroutine resumes inside it), so the base is
    searched: the lowest counted address is one of the instructions."""
    addrs = sorted(ir)
    found = []
    for func, code in funcs:
        # llvmpipe prints at most 96 KB of a function: what lies past its
        # end cannot be checked.
        end = max(code)
        for offset in code:
            base = addrs[0] - offset
            listed = [a for a in addrs if a - base <= end]
            probe = listed[:: max(1, len(listed) // 64)]
            if all(a - base in code for a in probe) and all(a - base in code for a in listed):
                found.append((func, code, base))
    if not found:
        sys.exit("no printed function matches the counted addresses")
    # The biggest, as a short one could match by chance.
    return max(found, key=lambda f: len(f[1]))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("glint")
    ap.add_argument("scene")
    ap.add_argument("--classes", type=int, default=12)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out, log = run(args.glint, args.scene, tmp)
        funcs = printed_functions(log)
        ir = counts(out)
    func, code, base = locate(funcs, ir)
    total = sum(ir.values())
    classes = collections.defaultdict(list)
    unlisted = 0
    for a, n in ir.items():
        if n:
            classes[n].append(code.get(a - base, ""))
            unlisted += n if a - base not in code else 0
    print(f"{func}: {total:,} instructions run, {len(code):,} in its printed code")
    if unlisted:
        print(f"({unlisted:,} of them past the printed 96 KB: in the classes by run count, "
              "not in the columns of instruction kinds)")
    print("| runs | instructions | share | gathered words | stack-frame moves | blends |")
    print("|---:|---:|---:|---:|---:|---:|")
    ranked = sorted(classes.items(), key=lambda kv: -kv[0] * len(kv[1]))
    for n, body in ranked[: args.classes]:
        gathers = sum(1 for t in body if t.startswith("vpinsrd\t$3, (")) / 2
        frame = sum(1 for t in body if "(%rsp)" in t and t.startswith("vmov"))
        blends = sum(1 for t in body if "blendv" in t)
        share = 100 * n * len(body) / total
        print(f"| {n:,} | {len(body)} | {share:.1f}% | {gathers:g} | {frame} | {blends} |")


if __name__ == "__main__":
    main()
