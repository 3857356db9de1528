#!/usr/bin/env python3
"""Instructions per inlined function from a callgrind profile.

callgrind_annotate charges inlined code to the function it was inlined into; in a release
build of the FMU most of the work (the Rosenbrock stages, the guard dot products, the
propagation) is inlined into two or three functions. This script reads a profile recorded
with per-instruction counts and asks addr2line which (innermost inlined) function and source
line each instruction belongs to:

    CARGO_PROFILE_RELEASE_DEBUG=line-tables-only CARGO_TARGET_DIR=target/profile \\
        cargo build --release -p ehsv-actuator
    cargo build --release -p ehsv-tests --bin bench
    valgrind --tool=callgrind --dump-instr=yes --callgrind-out-file=/tmp/gait.cg \\
        --toggle-collect=fmi2DoStep target/release/bench \\
        --lib target/profile/release/libehsv_actuator.so \\
        --only gait_position --h 1e-4 --fmi 2 --no-peer --repeat 1 --t-end 0.2
    scripts/callgrind-inlined.py /tmp/gait.cg target/profile/release/libehsv_actuator.so \\
        --calls 4000

`--calls N` divides the counts by N (the doSteps counted: `--repeat 1` runs twice, so
0.2 s at 1e-4 s is 4000 calls). Only the library's own instructions are counted (libm's
exp and tanh are not).
"""

import argparse
import collections
import re
import subprocess
import sys

POSITION = re.compile(r"^(0x[0-9a-f]+|\+\d+|-\d+|\*)\s+\S+\s+(\d+)")


def instruction_costs(profile, library):
    """Self cost per instruction address of `library` in a --dump-instr=yes profile."""
    costs = collections.Counter()
    objects = {}
    in_library = False
    address = 0
    skip_call_line = False
    with open(profile) as lines:
        for line in lines:
            if line.startswith("ob="):
                match = re.match(r"ob=\((\d+)\)(?: (.*))?", line.strip())
                if match.group(2):
                    objects[match.group(1)] = match.group(2)
                in_library = objects.get(match.group(1), "").endswith(library)
                continue
            if line.startswith("calls="):
                # The next position line is the call's inclusive cost, not this function's.
                skip_call_line = True
                continue
            match = POSITION.match(line)
            if not match:
                continue
            step = match.group(1)
            if step.startswith("0x"):
                address = int(step, 16)
            elif step[0] in "+-":
                address += int(step)
            if skip_call_line:
                skip_call_line = False
                continue
            if in_library:
                costs[address] += int(match.group(2))
    return costs


def innermost_frames(library, addresses):
    """Address -> (function, file:line) of the innermost inlined frame, by addr2line."""
    query = "\n".join(hex(a) for a in addresses)
    out = subprocess.run(
        ["addr2line", "-e", library, "-i", "-f", "-C", "-a"],
        input=query,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.splitlines()
    frames = {}
    current = None
    i = 0
    while i < len(out):
        if out[i].startswith("0x"):
            current = int(out[i], 16)
            i += 1
            continue
        if current is not None and current not in frames and i + 1 < len(out):
            function = re.sub(r"<.*?>", "", out[i])
            frames[current] = (function, out[i + 1].split("/")[-1].split(" ")[0])
        i += 2
    return frames


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("profile", help="callgrind output recorded with --dump-instr=yes")
    parser.add_argument("library", help="the profiled library, built with line tables")
    parser.add_argument("--calls", type=float, default=1.0, help="divide counts by this")
    parser.add_argument("--top", type=int, default=30)
    args = parser.parse_args()
    library_name = args.library.split("/")[-1]
    costs = instruction_costs(args.profile, library_name)
    if not costs:
        sys.exit(f"no instructions of {library_name} in {args.profile}")
    frames = innermost_frames(args.library, sorted(costs))
    by_function = collections.Counter()
    by_line = collections.Counter()
    for address, cost in costs.items():
        function, line = frames.get(address, ("?", "?"))
        by_function[function] += cost
        by_line[line] += cost
    total = sum(costs.values())
    print(f"{total / args.calls:,.0f} instructions per call in {library_name}")
    for title, table in (("innermost function", by_function), ("source line", by_line)):
        print(f"\n{'per call':>10} {'share':>6}  {title}")
        for name, cost in table.most_common(args.top):
            print(f"{cost / args.calls:10,.0f} {100 * cost / total:5.1f}%  {name[:100]}")


if __name__ == "__main__":
    main()
