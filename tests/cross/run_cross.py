"""Runs the multi-platform archives on the platforms this machine can run or emulate and
checks the ones it can only inspect (scripts/test-cross.sh calls this after
`cargo run --release -p build-fmu -- --all-targets`).

- x86_64-linux (portable build): needs at most GLIBC_2.17 (objdump -T) and runs here.
- x86_64-windows: a harness built with mingw loads the DLL from the unzipped archive under
  Wine; the DLL imports only system DLLs.
- aarch64-linux: the harness, built with zig cc, runs under qemu-user; at most GLIBC_2.17.
- x86_64-darwin, aarch64-darwin: Mach-O dynamic libraries of the right CPU (link-checked
  here, run-tested on macOS by .github/workflows/release.yml).
Every run steps a current step and a flow step through the FMI 2.0 and FMI 3.0 C APIs;
outputs equal the x86_64 Linux binary's within 1e-12 relative at every communication
point (they differ in the last digits only through the platform's libm), and the portable
Linux binary equals the native host build (target/release) where that exists.

usage: python tests/cross/run_cross.py [FMU_DIR]   (default target/fmu)
"""

import os
import re
import shutil
import struct
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent
WINE = "/usr/lib/wine/wine64"  # Debian's wine64 package does not put it on PATH
AARCH64_SYSROOT = "/usr/aarch64-linux-gnu"  # libc6-arm64-cross
MAX_GLIBC = (2, 17)
RELATIVE = 1e-12
OUTPUTS = ("i_coil", "u_driver", "x_spool", "Q_valve", "Q_A", "p_A", "x_piston", "v_piston")
# (name, steps, step size, settings by variable name: (when, value)); "init" before
# initialisation, "step" at t = 0 after it: a step input from equilibrium.
SCENARIOS = (
    ("current step", 100, 1e-4, {"i_ref": ("step", 5e-3)}),
    ("flow step", 300, 1e-4, {"control_mode": ("init", 1), "Q_ref": ("step", 2e-4)}),
)
# What a Windows DLL built by this route may import: Windows' own libraries.
SYSTEM_DLLS = {
    "kernel32.dll",
    "msvcrt.dll",
    "ntdll.dll",
    "userenv.dll",
    "ws2_32.dll",
    "bcryptprimitives.dll",
    "advapi32.dll",
    "bcrypt.dll",
    "api-ms-win-core-synch-l1-2-0.dll",
}
MACHO_CPU = {"x86_64-darwin": 0x01000007, "aarch64-darwin": 0x0100000C}

failures = []


def check(ok, message):
    print(("ok    " if ok else "FAIL  ") + message)
    if not ok:
        failures.append(message)


def run(command, **kw):
    return subprocess.run(command, check=True, capture_output=True, text=True, **kw).stdout


def zig_cc():
    """zig from the ziglang wheel in this Python's environment."""
    return [sys.executable, "-m", "ziglang", "cc"]


def build_harnesses(work):
    src = str(HERE / "harness.c")
    flags = ["-std=c99", "-O1", "-Wall", "-Wextra", "-Werror"]
    built = {
        "native": work / "harness",
        "windows": work / "win" / "harness.exe",
        "aarch64": work / "harness-aarch64",
    }
    (work / "win").mkdir()
    run(["cc", *flags, "-o", str(built["native"]), src, "-ldl"])
    run(["x86_64-w64-mingw32-gcc", *flags, "-o", str(built["windows"]), src])
    run(
        [
            "x86_64-w64-mingw32-gcc",
            "-shared",
            "-O1",
            "-Wall",
            "-o",
            str(work / "win" / "bcryptprimitives.dll"),
            str(HERE / "process_prng_shim.c"),
            "-lbcrypt",
        ]
    )
    run([*zig_cc(), "-target", "aarch64-linux-gnu.2.17", *flags, "-o", str(built["aarch64"]), src])
    return built


def model(unzipped):
    root = ET.parse(unzipped / "modelDescription.xml").getroot()
    token = root.get("guid") or root.get("instantiationToken")
    variables = root.find("ModelVariables")
    vrs = {v.get("name"): v.get("valueReference") for v in variables}
    return token, vrs


def harness_args(version, unzipped, scenario):
    _, steps, h, settings = scenario
    token, vrs = model(unzipped)
    args = [version, token, "", str(steps), repr(h), ",".join(vrs[n] for n in OUTPUTS)]
    for name, (when, value) in settings.items():
        kind = "R" if when == "step" else ("i" if isinstance(value, int) else "r")
        args.append(f"{kind}{vrs[name]}={value!r}")
    return args


def parse(text):
    return [[float(x) for x in line.split()] for line in text.strip().splitlines()]


def equal(a, b):
    """Every value within RELATIVE of the other; returns the worst relative difference."""
    if len(a) != len(b):
        return False, float("inf")
    worst = 0.0
    for row_a, row_b in zip(a, b, strict=True):
        for x, y in zip(row_a, row_b, strict=True):
            scale = max(abs(x), abs(y))
            if scale > 0:
                worst = max(worst, abs(x - y) / scale)
    return worst <= RELATIVE, worst


def highest_glibc(library):
    versions = re.findall(r"GLIBC_(\d+)\.(\d+)", run(["objdump", "-T", str(library)]))
    return max((int(a), int(b)) for a, b in versions)


def main():
    fmu_dir = Path(sys.argv[1]) if len(sys.argv) > 1 else REPO / "target" / "fmu"
    work = Path(tempfile.mkdtemp(prefix="ehsv-cross-"))
    try:
        harness = build_harnesses(work)
        env = dict(os.environ, WINEPREFIX=str(work / "wineprefix"), WINEDEBUG="-all")
        for version, platforms in (
            ("fmi2", ("linux64", "win64", "darwin64")),
            ("fmi3", ("x86_64-linux", "aarch64-linux", "x86_64-windows", "x86_64-darwin", "aarch64-darwin")),
        ):
            unzipped = work / version
            with zipfile.ZipFile(fmu_dir / f"EhsvActuator-{version}.fmu") as z:
                z.extractall(unzipped)
            binaries = unzipped / "binaries"
            present = sorted(p.name for p in binaries.iterdir())
            check(present == sorted(platforms), f"{version}: binaries for {', '.join(platforms)} ({present})")
            linux, windows = platforms[0], platforms[-3 if version == "fmi3" else 1]
            so = binaries / linux / "EhsvActuator.so"
            dll = binaries / windows / "EhsvActuator.dll"
            glibc = highest_glibc(so)
            check(
                glibc <= MAX_GLIBC, f"{version} {linux}: highest GLIBC symbol version {glibc} <= {MAX_GLIBC}"
            )
            imports = {
                m.lower()
                for m in re.findall(r"DLL Name: (\S+)", run(["x86_64-w64-mingw32-objdump", "-p", str(dll)]))
            }
            check(
                imports <= SYSTEM_DLLS,
                f"{version} {windows}: imports only system DLLs ({sorted(imports - SYSTEM_DLLS)} else)",
            )
            runners = {
                "windows": (
                    [WINE, str(harness["windows"]), "Z:" + str(dll).replace("/", "\\")],
                    {"cwd": harness["windows"].parent},
                ),
            }
            if version == "fmi3":
                arm = binaries / "aarch64-linux" / "EhsvActuator.so"
                check(
                    highest_glibc(arm) <= MAX_GLIBC,
                    f"fmi3 aarch64-linux: highest GLIBC symbol version <= {MAX_GLIBC}",
                )
                runners["aarch64"] = (
                    ["qemu-aarch64", "-L", AARCH64_SYSROOT, str(harness["aarch64"]), str(arm)],
                    {},
                )
            native = REPO / "target" / "release" / "libehsv_actuator.so"
            if native.exists():
                runners["native host build"] = ([str(harness["native"]), str(native)], {})
            for scenario in SCENARIOS:
                args = harness_args(version, unzipped, scenario)
                reference = parse(run([str(harness["native"]), str(so), *args]))
                check(
                    len(reference) == scenario[1] + 1 and reference[-1][1] != 0.0,
                    f"{version} {linux} {scenario[0]}: runs, {len(reference)} points, moving",
                )
                for name, (command, kw) in runners.items():
                    got = parse(run([*command, *args], env=env, **kw))
                    ok, worst = equal(got, reference)
                    check(
                        ok,
                        f"{version} {name} {scenario[0]}: equals {linux} (worst relative {worst:.1e})",
                    )
            for platform in platforms:
                if platform in MACHO_CPU or platform == "darwin64":
                    cpu = MACHO_CPU["x86_64-darwin" if platform == "darwin64" else platform]
                    head = (binaries / platform / "EhsvActuator.dylib").read_bytes()[:16]
                    magic, cputype, _, filetype = struct.unpack("<IIII", head)
                    check(
                        (magic, cputype, filetype) == (0xFEEDFACF, cpu, 6),
                        f"{version} {platform}: a 64-bit Mach-O dylib for CPU {cpu:#x}",
                    )
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print(f"{len(failures)} failed" if failures else "cross-platform checks: all passed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
