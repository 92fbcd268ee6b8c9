"""Times horus-gen against capnp compile and lcm-gen, and the compile cost of their headers.

Run through run.sh, which checks the tools first. The commands of each part run round-robin:
one untimed round to warm the page cache, then `--gen-reps`/`--cxx-reps` timed rounds; the
tables report the median and the minimum wall time of each.
A failed command stops the run with its output and a non-zero exit: a benchmark of a broken
build is not a result.
"""

import argparse
import datetime
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
SCHEMAS = HERE / "schemas"
HMSG = sorted((SCHEMAS / "bench_msgs").glob("*.hmsg"))
CAPNP = HERE / "capnp" / "bench_msgs.capnp"
LCM = sorted((HERE / "lcm").glob("*.lcm"))
HORUS_GEN = [sys.executable, str(ROOT / "generator" / "horus-gen")]
CXX = ["g++", "-std=c++20", "-fsyntax-only"]
# A library's sources compile as CMake's default build type here (RelWithDebInfo) compiles them.
CXX_OBJECT = ["g++", "-std=c++20", "-O2", "-g", "-c"]

# The "typical POD message" rows: one flat message without strings, and one that nests a
# Header (which holds a string<32>, an LCM `string`): LCM's header for the latter pulls in <string>.
POD_FLAT = ("MotorFeedback", "motor_feedback")
POD_NESTED = ("Imu", "imu")


class BenchError(Exception):
    pass


def run(cmd, env=None):
    proc = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if proc.returncode != 0:
        raise BenchError(f"command failed (exit {proc.returncode}): {' '.join(map(str, cmd))}\n"
                         f"{proc.stdout}{proc.stderr}")
    return proc


class Case:
    """One timed command, or several run one after another (`cmds`); `before()` runs untimed
    before each run."""

    def __init__(self, cmd=None, before=None, env=None, cmds=None):
        self.cmds = cmds if cmds is not None else [cmd]
        self.before, self.env = before, env
        self.samples = []


def timed(cases, reps):
    """Median and minimum wall time in seconds of each case, by key.

    The cases run round-robin (one run of each per round) rather than one case after another, so
    a burst of load from other work on the machine spreads over all of them instead of
    inflating one row. Round 0 only warms the caches and is not counted."""
    for round_ in range(reps + 1):
        for case in cases.values():
            if case.before:
                case.before()
            start = time.perf_counter()
            for cmd in case.cmds:
                run(cmd, env=case.env)
            elapsed = time.perf_counter() - start
            if round_ > 0:
                case.samples.append(elapsed)
    return {key: (statistics.median(c.samples), min(c.samples)) for key, c in cases.items()}


def fresh(path):
    def reset():
        shutil.rmtree(path, ignore_errors=True)
        path.mkdir(parents=True)
    return reset


def snapshot(folder):
    return {p: p.stat().st_mtime_ns for p in folder.rglob("*") if p.is_file()}


def tree_size(folder, pattern):
    files = [p for p in folder.rglob(pattern) if p.is_file()]
    return len(files), sum(p.stat().st_size for p in files)


def horus_gen_cmd(out, langs):
    return HORUS_GEN + ["generate", "--lang", langs, "--out", str(out), "-I", str(SCHEMAS)] + \
        [str(p) for p in HMSG]


def python_env(work, bytecode):
    """The environment horus-gen runs in. With `bytecode`, compiled modules are cached (in the
    work folder, never in the source tree), as they are for any installed Python program; without
    it every run compiles horus_gen from source."""
    env = dict(os.environ)
    if bytecode:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = str(work / "pycache")
    else:
        env["PYTHONDONTWRITEBYTECODE"] = "1"
        env.pop("PYTHONPYCACHEPREFIX", None)
    return env


def python_supported(work):
    probe = work / "probe"
    proc = subprocess.run(horus_gen_cmd(probe, "cpp,python"), env=python_env(work, True),
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if proc.returncode == 0:
        return True, ""
    if proc.returncode == 2 and "python" in proc.stderr:
        return False, proc.stderr.strip()
    raise BenchError(f"horus-gen --lang cpp,python failed (exit {proc.returncode}):\n{proc.stderr}")


def tool_version(cmd):
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    return proc.stdout.strip().splitlines()[0] if proc.stdout.strip() else "?"


def machine():
    cpu = "?"
    with open("/proc/cpuinfo") as f:
        for line in f:
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    return {
        "nproc": str(os.cpu_count()),
        "cpu": cpu,
        "cxx": tool_version(["g++", "--version"]),
        "capnp": tool_version(["capnp", "--version"]),
        "lcm-gen": tool_version(["lcm-gen", "--version"]),
        "python": platform.python_version(),
        "kernel": platform.release(),
    }


def git_revision():
    proc = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                          stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    rev = proc.stdout.strip() or "?"
    dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--", "generator",
                            "templates", "runtime/include/horus"],
                           stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True).stdout
    return rev + (" + uncommitted changes in generator/templates/runtime headers" if dirty else "")


def fmt(seconds):
    return f"{seconds * 1000:.1f} ms" if seconds < 1 else f"{seconds:.2f} s"


def ratio(a, b):
    return f"{a / b:.2f}x" if b > 0 else "n/a"


def bench_generation(work, reps):
    env = python_env(work, bytecode=True)
    out = work / "gen-horus-cpp"
    incremental = work / "gen-horus-incremental"
    run(horus_gen_cmd(incremental, "cpp"), env=env)
    if not (incremental / "cpp" / "bench_msgs.hpp").is_file():
        raise BenchError("horus-gen did not write cpp/bench_msgs.hpp")
    before = snapshot(incremental)

    cases = {
        "horus_cold": Case(horus_gen_cmd(out, "cpp"), before=fresh(out), env=env),
        "horus_incremental": Case(horus_gen_cmd(incremental, "cpp"), env=env),
    }
    ok, why = python_supported(work)
    if ok:
        both = work / "gen-horus-both"
        cases["horus_both_cold"] = Case(horus_gen_cmd(both, "cpp,python"), before=fresh(both),
                                        env=env)
    nocache = work / "gen-horus-nocache"
    cases["horus_nocache"] = Case(horus_gen_cmd(nocache, "cpp"), before=fresh(nocache),
                                  env=python_env(work, bytecode=False))
    cases["jinja_floor"] = Case([sys.executable, "-c", "import jinja2"], env=env)
    capnp_out = work / "gen-capnp"
    cases["capnp"] = Case(["capnp", "compile", f"-oc++:{capnp_out}", f"--src-prefix={CAPNP.parent}",
                           str(CAPNP)], before=fresh(capnp_out))
    lcm_out = work / "gen-lcm"
    cases["lcm"] = Case(["lcm-gen", "--cpp", "--cpp-hpath", str(lcm_out)] + [str(p) for p in LCM],
                        before=fresh(lcm_out))

    rows = timed(cases, reps)
    rows["python_note"] = why
    rewritten = [p for p, t in snapshot(incremental).items() if before.get(p) != t]
    if rewritten:
        raise BenchError("an unchanged re-run rewrote files: " +
                         ", ".join(str(p.relative_to(incremental)) for p in rewritten[:5]))
    rows["sizes"] = {
        "horus": tree_size(out / "cpp", "*.hpp"),
        "capnp": tree_size(capnp_out, "*"),
        "lcm": tree_size(lcm_out, "*.hpp"),
    }
    return rows, out, capnp_out, lcm_out


def bench_headers(work, reps, horus_out, capnp_out, lcm_out):
    src = work / "tu"
    src.mkdir()

    def tu(name, *includes):
        path = src / f"{name}.cpp"
        path.write_text("".join(f"#include {inc}\n" for inc in includes))
        return path

    horus_flags = ["-I", str(ROOT / "runtime" / "include"), "-I", str(horus_out / "cpp"),
                   "-DMSGPACK_NO_BOOST"]
    lcm_flags = ["-I", str(lcm_out), "-I", "/usr/include"]
    capnp_flags = ["-I", str(capnp_out)]
    lcm_all = sorted((lcm_out / "bench_msgs").glob("*.hpp"))

    cases = [
        ("empty", "empty file", tu("empty"), []),
        ("string", "`<string>`", tu("string", "<string>"), []),
        ("string_vector", "`<string>` + `<vector>`", tu("string_vector", "<string>", "<vector>"), []),
        ("horus_all", "horus: umbrella `bench_msgs.hpp` (35 messages, 5 enums)",
         tu("horus_all", "<bench_msgs.hpp>"), horus_flags),
        ("lcm_all", "LCM: all 35 headers", tu("lcm_all", *[f"<bench_msgs/{p.name}>" for p in lcm_all]),
         lcm_flags),
        ("capnp_all", "capnp: `bench_msgs.capnp.h` (all 35 structs, one header)",
         tu("capnp_all", '"bench_msgs.capnp.h"'), capnp_flags),
        ("horus_flat", f"horus: one POD message, `{POD_FLAT[1]}.hpp`",
         tu("horus_flat", f"<bench_msgs/{POD_FLAT[1]}.hpp>"), horus_flags),
        ("lcm_flat", f"LCM: one POD message, `{POD_FLAT[0]}.hpp`",
         tu("lcm_flat", f"<bench_msgs/{POD_FLAT[0]}.hpp>"), lcm_flags),
        ("horus_nested", f"horus: one POD message with nested Header, `{POD_NESTED[1]}.hpp`",
         tu("horus_nested", f"<bench_msgs/{POD_NESTED[1]}.hpp>"), horus_flags),
        ("lcm_nested", f"LCM: one POD message with nested Header, `{POD_NESTED[0]}.hpp`",
         tu("lcm_nested", f"<bench_msgs/{POD_NESTED[0]}.hpp>"), lcm_flags),
    ]
    times = timed({key: Case(CXX + flags + [str(path)]) for key, _, path, flags in cases}, reps)
    return {key: (label,) + times[key] for key, label, _, _ in cases}


def bench_cold_build(work, reps, env):
    """The cold build of the package's generated C++, each step as a build runs it: generate into
    an empty folder, compile every generated source one at a time, and one translation unit that
    includes every generated header (-fsyntax-only); horus-gen and capnp side by side."""
    horus_out, capnp_out = work / "cold-horus", work / "cold-capnp"
    capnp_cmd = ["capnp", "compile", f"-oc++:{capnp_out}", f"--src-prefix={CAPNP.parent}", str(CAPNP)]
    run(horus_gen_cmd(horus_out, "cpp"), env=env)
    fresh(capnp_out)()
    run(capnp_cmd)
    horus_sources = sorted((horus_out / "cpp").rglob("*.cpp"))
    capnp_sources = sorted(capnp_out.rglob("*.c++"))
    horus_flags = ["-I", str(ROOT / "runtime" / "include"), "-I", str(horus_out / "cpp"), "-DMSGPACK_NO_BOOST"]
    capnp_flags = ["-I", str(capnp_out)]
    tu = work / "cold-tu"
    tu.mkdir()
    horus_all = tu / "horus_every_header.cpp"
    horus_all.write_text("".join(f'#include "{h.relative_to(horus_out / "cpp")}"\n'
                                 for h in sorted((horus_out / "cpp").rglob("*.hpp"))))
    capnp_all = tu / "capnp_every_header.cpp"
    capnp_all.write_text("".join(f'#include "{h.relative_to(capnp_out)}"\n' for h in sorted(capnp_out.rglob("*.h"))))
    objects = work / "cold-objects"
    objects.mkdir()

    def compile_each(sources, flags):
        return [CXX_OBJECT + flags + [str(src), "-o", str(objects / (src.name + ".o"))] for src in sources]

    cases = {
        "horus_generate": Case(horus_gen_cmd(horus_out, "cpp"), before=fresh(horus_out), env=env),
        "capnp_generate": Case(capnp_cmd, before=fresh(capnp_out)),
    }
    times = timed(cases, reps)
    # Sources and headers are compiled from a generated copy that stays in place.
    run(horus_gen_cmd(horus_out, "cpp"), env=env)
    run(capnp_cmd)
    times.update(timed({
        "horus_sources": Case(cmds=compile_each(horus_sources, horus_flags)),
        "capnp_sources": Case(cmds=compile_each(capnp_sources, capnp_flags)),
        "horus_headers": Case(CXX + horus_flags + [str(horus_all)]),
        # What the package's .cpp costs before any code of its own: it includes every header.
        "horus_source_floor": Case(CXX_OBJECT + horus_flags + [str(horus_all), "-o", str(objects / "floor.o")]),
        "capnp_headers": Case(CXX + capnp_flags + [str(capnp_all)]),
    }, reps))
    times["counts"] = {"horus": (len(horus_sources), len(list((horus_out / "cpp").rglob("*.hpp")))),
                       "capnp": (len(capnp_sources), len(list(capnp_out.rglob("*.h"))))}
    return times


def bench_python_import(work, reps, env):
    """`import horus.msg` (the standard library generated for Python) against `import numpy`, each
    in a fresh interpreter, with the interpreter's start-up as the floor."""
    out = work / "py-std"
    std = ROOT / "schemas"
    run(HORUS_GEN + ["generate", "--lang", "python", "--out", str(out), "-I", str(std)] +
        [str(p) for p in sorted((std / "horus" / "msg").glob("*.hmsg"))], env=env)
    py_env = dict(env, PYTHONPATH=str(out / "python"))
    return timed({
        "floor": Case([sys.executable, "-c", "pass"], env=py_env),
        "horus_msg": Case([sys.executable, "-c", "import horus.msg"], env=py_env),
        "numpy": Case([sys.executable, "-c", "import numpy"], env=py_env),
    }, reps)


def report_cold(cold, py):
    lines = []
    add = lines.append
    add("## Cold build of the package's generated C++ (goal: <= 0.5x Cap'n Proto)")
    add("")
    (hs, hh), (cs, ch) = cold["counts"]["horus"], cold["counts"]["capnp"]
    add(f"Generate into an empty folder; compile every generated source one at a time "
        f"(`{' '.join(CXX_OBJECT)}`: horus {hs} `.cpp`, capnp {cs} `.c++`); one translation unit "
        f"including every generated header (`{' '.join(CXX)}`: horus {hh}, capnp {ch}).")
    add("")
    add("| step | horus-gen (median) | Cap'n Proto (median) | horus / capnp |")
    add("|---|---:|---:|---:|")
    total_h = total_c = 0.0
    for key, label in [("generate", "generate (C++)"), ("sources", "compile every generated source"),
                       ("headers", "one TU including every header, -fsyntax-only")]:
        h, c = cold[f"horus_{key}"][0], cold[f"capnp_{key}"][0]
        total_h, total_c = total_h + h, total_c + c
        add(f"| {label} | {fmt(h)} | {fmt(c)} | {ratio(h, c)} |")
    verdict = "met" if total_h <= 0.5 * total_c else "NOT met"
    add(f"| **cold build** | **{fmt(total_h)}** | **{fmt(total_c)}** | **{ratio(total_h, total_c)}** "
        f"(goal <= 0.50x: {verdict}) |")
    add("")
    floor = cold["horus_source_floor"][0]
    add(f"Floor of horus's `.cpp`: the same compile of a file that only includes every header takes "
        f"{fmt(floor)}, so the package's own code (log summary tables, layout checks) costs "
        f"{fmt(max(cold['horus_sources'][0] - floor, 0.0))} of the {fmt(cold['horus_sources'][0])}. Neither "
        f"side counts its runtime library, compiled once per installation (capnp's `libcapnp`, horus's "
        f"`horus::summary`, the formatter the summary tables are read by).")
    add("")
    add("## Python: importing the generated standard library")
    add("")
    add("| fresh interpreter running | median | min | above `pass` |")
    add("|---|---:|---:|---:|")
    floor = py["floor"][0]
    for key, label in [("floor", "`pass`"), ("horus_msg", "`import horus.msg`"), ("numpy", "`import numpy`")]:
        med, lo = py[key]
        add(f"| {label} | {fmt(med)} | {fmt(lo)} | {fmt(max(med - floor, 0.0))} |")
    add("")
    verdict = "met" if py["horus_msg"][0] <= py["numpy"][0] else "NOT met"
    add(f"`import horus.msg` / `import numpy`: {ratio(py['horus_msg'][0], py['numpy'][0])} "
        f"(goal <= 1.00x: {verdict}).")
    add("")
    return "\n".join(lines)


def report(args, gen, hdr, info):
    base = hdr["empty"][1]
    above = {k: max(v[1] - base, 0.0) for k, v in hdr.items()}
    base_min = hdr["empty"][2]
    above_min = {k: max(v[2] - base_min, 0.0) for k, v in hdr.items()}
    lines = []
    add = lines.append
    add("# horus-gen benchmark results")
    add("")
    add(f"- Command: `{args.command}`")
    add(f"- Date: {info['date']}")
    add(f"- Machine: {info['nproc']} CPUs, {info['cpu']}, Linux {info['kernel']}, "
        f"load average {info['load']} at start")
    add(f"- Compiler: {info['cxx']}; Python {info['python']}; {info['capnp']}; {info['lcm-gen']}")
    add(f"- horus revision: {info['rev']}")
    add(f"- Repetitions: {args.gen_reps} per generator, {args.cxx_reps} per compile "
        "(after one untimed warm-up run); wall time, median and minimum")
    add("")
    add("## Generation of the 35-message package")
    add("")
    add("| generator | median | min | this / capnp |")
    add("|---|---:|---:|---:|")
    cold = gen["horus_cold"][0]
    capnp = gen["capnp"][0]
    gen_rows = [
        ("horus-gen --lang cpp, cold (empty output folder)", gen["horus_cold"]),
        ("horus-gen --lang cpp, incremental (nothing changed, nothing rewritten)",
         gen["horus_incremental"]),
    ]
    if "horus_both_cold" in gen:
        gen_rows.append(("horus-gen --lang cpp,python, cold", gen["horus_both_cold"]))
    gen_rows += [
        ("horus-gen --lang cpp, cold, without a bytecode cache (PYTHONDONTWRITEBYTECODE=1)",
         gen["horus_nocache"]),
        ("floor of any Jinja2 generator: `python3 -c 'import jinja2'`", gen["jinja_floor"]),
        ("capnp compile -oc++", gen["capnp"]),
        ("lcm-gen --cpp", gen["lcm"]),
    ]
    for label, (med, lo) in gen_rows:
        add(f"| {label} | {fmt(med)} | {fmt(lo)} | {ratio(med, capnp)} |")
    if "horus_both_cold" not in gen:
        add("| horus-gen --lang cpp,python | not measured: the Python emitter does not exist yet "
            f"(`{gen['python_note']}`) | | |")
    add("")
    sizes = gen["sizes"]
    add("Output: " + "; ".join(f"{k} {n} files, {b / 1024:.0f} KiB" for k, (n, b) in sizes.items()) + ".")
    add("")
    add("## `g++ -std=c++20 -fsyntax-only` of one file including generated headers")
    add("")
    add("\"Above empty\" subtracts the empty file's time (compiler start-up), which is what the "
        "headers themselves cost.")
    add("")
    add("| translation unit | median | min | above empty |")
    add("|---|---:|---:|---:|")
    for key, (label, med, lo) in hdr.items():
        add(f"| {label} | {fmt(med)} | {fmt(lo)} | {fmt(above[key])} |")
    add("")
    add("## Ratios (headers: time above the empty file)")
    add("")
    add("The goal verdict uses the medians; the ratio of the minima is the steadier figure when "
        "other work loads the machine.")
    add("")
    add("| comparison | ratio of medians | ratio of minima | goal |")
    add("|---|---:|---:|---|")
    gen_goal = "met" if cold <= capnp else "NOT met"
    add(f"| generation: horus cold / capnp | {ratio(cold, capnp)} | "
        f"{ratio(gen['horus_cold'][1], gen['capnp'][1])} | "
        f"<= 1.00x ({gen_goal}) |")
    add(f"| generation: horus cold / lcm-gen | {ratio(cold, gen['lcm'][0])} | "
        f"{ratio(gen['horus_cold'][1], gen['lcm'][1])} | |")
    if "horus_both_cold" in gen:
        add(f"| generation: horus cpp,python / capnp | {ratio(gen['horus_both_cold'][0], capnp)} | "
            f"{ratio(gen['horus_both_cold'][1], gen['capnp'][1])} | |")
    for a, b, label, goal in [
            ("horus_all", "lcm_all", "all headers: horus / LCM", 0.5),
            ("horus_all", "capnp_all", "all headers: horus / capnp", None),
            ("horus_flat", "lcm_flat", f"one POD message ({POD_FLAT[0]}): horus / LCM", 0.5),
            ("horus_nested", "lcm_nested", f"one POD message ({POD_NESTED[0]}): horus / LCM", 0.5),
            ("string", "lcm_all", "`<string>` / all LCM headers", None),
            ("string_vector", "lcm_all", "`<string>` + `<vector>` / all LCM headers", None)]:
        verdict = ""
        if goal is not None and above[b] > 0:
            verdict = f"<= {goal:.2f}x ({'met' if above[a] <= goal * above[b] else 'NOT met'})"
        add(f"| {label} | {ratio(above[a], above[b])} | {ratio(above_min[a], above_min[b])} | "
            f"{verdict} |")
    add("")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--gen-reps", type=int, default=20, help="timed runs per generator")
    parser.add_argument("--cxx-reps", type=int, default=9, help="timed runs per compile")
    parser.add_argument("--results", default=str(HERE / "RESULTS.md"), help="markdown output")
    parser.add_argument("--command", default="bench/generator/run.sh",
                        help="the command line recorded in the results")
    args = parser.parse_args()
    if args.gen_reps < 1 or args.cxx_reps < 1:
        parser.error("repetitions must be at least 1")
    if len(HMSG) == 0 or len(LCM) != 35 or not CAPNP.is_file():
        raise BenchError(f"schemas missing under {HERE}")

    info = machine()
    info["date"] = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    info["load"] = " ".join(f"{x:.2f}" for x in os.getloadavg())
    info["rev"] = git_revision()

    with tempfile.TemporaryDirectory(prefix="horus-genbench-") as tmp:
        work = Path(tmp)
        print(f"generation: {args.gen_reps} runs each ...", flush=True)
        gen, horus_out, capnp_out, lcm_out = bench_generation(work, args.gen_reps)
        print(f"headers: {args.cxx_reps} compiles each ...", flush=True)
        hdr = bench_headers(work, args.cxx_reps, horus_out, capnp_out, lcm_out)
        print(f"cold build: {args.cxx_reps} runs of each step ...", flush=True)
        cold = bench_cold_build(work, args.cxx_reps, python_env(work, bytecode=True))
        print(f"python import: {args.gen_reps} runs each ...", flush=True)
        py = bench_python_import(work, args.gen_reps, python_env(work, bytecode=True))

    text = report(args, gen, hdr, info) + "\n" + report_cold(cold, py)
    print()
    print(text)
    Path(args.results).write_text(text)
    print(f"written to {args.results}")


if __name__ == "__main__":
    try:
        main()
    except BenchError as e:
        print(f"bench/generator: error: {e}", file=sys.stderr)
        sys.exit(1)
