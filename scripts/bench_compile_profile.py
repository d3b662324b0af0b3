"""Where a preset's or a pair's XLA compile time goes: each program (init, chunk, evaluate) traced, lowered
and compiled as `rlq train` does, one at a time or side by side, with the host's CPU use sampled and,
optionally, under JAX's profiler (XLA's own host trace: HLO passes, LLVM, ptxas, autotuning).

    python scripts/bench_compile_profile.py --preset lunar_ppo_gpu --profile --out compile_profile.json
    python scripts/bench_compile_profile.py --preset humanoid_ppo --side-by-side \\
        --override budget.env_steps=10500000 --xla-option xla_gpu_autotune_level=0
    python scripts/bench_compile_profile.py --pair pqn lunar --machine gpu --by-source 30 \\
        --override budget.env_steps=1000000 env.solver.sweep_layout=components

``--pair ALGO ENV`` composes `rlq train algo=ALGO env=ENV machine=MACHINE` (the pair's tuned recipe for
``--machine``, gpu by default) instead of a preset. On a CPU, LunarLander's solver is traced in its CPU
form unless ``env.solver.sweep_layout=components`` asks for the GPU's.

Per program: trace and lowering seconds, XLA compile seconds and the CPU seconds this process spent
on them (``compile_cpu_s``: steadier than the wall time where other work shares the cores; side by
side, all programs' together), the host's busy cores while it compiled (mean and peak of /proc/stat
samples every 0.2 s), and the optimized module's size (HLO instructions, fusions, custom calls, while
loops) and the traced program's size (``jaxpr_equations``: every loop body once; what XLA starts from on any
platform). ``--by-source N``: the N rlq functions whose calls the most optimized HLO instructions and traced
equations came from (each counted once for every rlq function on its stack). ``load`` holds the host's load averages (1, 5, 15 min) at the start and at the end. With ``--profile``: the profiler's host events
summed by name (top ``--top``) and the number of host threads that were busy. Run each variant in
its own process: XLA keeps autotuning results and compiled kernels in memory for the process.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import re
import resource
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

T_START = time.perf_counter()
LOAD_START = [round(load, 2) for load in os.getloadavg()]

PROGRAMS = ("chunk", "init", "evaluate")


def cpu_seconds() -> float:
    """User and system CPU seconds of this process so far, all threads (XLA compiles on several)."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def module_size(compiled) -> dict:
    """Counts in the optimized HLO text: instructions, fusions (GPU kernels, mostly) by kind, custom
    calls by target, while loops (with their known trip counts)."""
    try:
        text = compiled.as_text()
    except Exception as err:  # some executables have no text
        return {"error": str(err)[:200]}
    ops = collections.Counter(re.findall(r"\s([a-z][a-z0-9-]*)\((?:%|\))", text))
    return {
        "hlo_chars": len(text),
        "instructions": len(re.findall(r"^\s+(?:ROOT )?%\S+ = ", text, flags=re.M)),
        "ops_top": ops.most_common(12),
        "fusion_kinds": collections.Counter(re.findall(r"kind=(k[A-Za-z]+)", text)).most_common(),
        "backend_kinds": collections.Counter(re.findall(r'"kind":"([^"]+)"', text)).most_common(8),
        "custom_call_targets": collections.Counter(re.findall(r'custom_call_target="([^"]+)"', text)).most_common(8),
        "while": len(re.findall(r"\swhile\(", text)),
        "known_trip_counts": collections.Counter(re.findall(r'"known_trip_count":\{"n":"(\d+)"', text)).most_common(12),
    }


def stack_frames(text: str) -> tuple[dict[int, tuple[str, str]], dict[int, tuple[int, int]]]:
    """The stack frame tables of an HLO module's text: file location id -> (file, function), and frame
    id -> (file location id, parent frame id; 0: none)."""
    files: dict[int, str] = {}
    functions: dict[int, str] = {}
    locations: dict[int, tuple[str, str]] = {}
    frames: dict[int, tuple[int, int]] = {}
    section = None
    for line in text.splitlines():
        if line in ("FileNames", "FunctionNames", "FileLocations", "StackFrames"):
            section = line
            continue
        match = re.match(r"(\d+) (.*)$", line) if section else None
        if match is None:
            if line.startswith(("HloModule", "ENTRY", "%")):
                section = None
            continue
        key, rest = int(match.group(1)), match.group(2)
        fields = {k: int(v) for k, v in re.findall(r"(\w+)=(\d+)", rest)}
        if section == "FileNames":
            files[key] = rest.strip('"')
        elif section == "FunctionNames":
            functions[key] = rest.strip('"')
        elif section == "FileLocations":
            locations[key] = (files[fields["file_name_id"]], functions[fields["function_name_id"]])
        else:  # the text writes a frame's parent as its id + 1 (0: none)
            frames[key] = (fields["file_location_id"], fields["parent_frame_id"] - 1)
    return locations, frames


def by_source(text: str, top: int) -> list[list]:
    """[rlq function, optimized HLO instructions traced under it] for the ``top`` functions: each instruction
    counted once for every rlq function on its stack (a loop body's stack starts inside the loop). Inner jitted
    functions JAX caches (``jnp.where``, PRNG hashing) keep the stack of their first trace: rough figures."""
    locations, frames = stack_frames(text)
    counts: collections.Counter = collections.Counter()
    for frame in re.findall(r"^\s+(?:ROOT )?%\S+ = .*?stack_frame_id=(\d+)", text, flags=re.M):
        fid, seen, names = int(frame), set(), set()
        while fid > 0 and fid in frames and fid not in seen:
            seen.add(fid)
            location, fid = frames[fid]
            path, function = locations[location]
            if "/rlq/" in path:
                names.add(f"{path.rsplit('/rlq/', 1)[1]}:{function}")
        counts.update(names)
    return [[name, count] for name, count in counts.most_common(top)]


def jaxpr_sources(jaxpr, counts: collections.Counter | None = None) -> collections.Counter:
    """The traced program's equations, each loop body, branch and inner jit counted once (what XLA starts from,
    the same on every platform but for ``platform_dependent``'s branches): under "" all of them, and under each rlq
    function the equations traced inside its calls (from the equations' tracebacks; a loop body's too)."""
    import jax

    counts = collections.Counter() if counts is None else counts
    for eqn in jaxpr.eqns:
        inner = [
            q.jaxpr if isinstance(q, jax.extend.core.ClosedJaxpr) else q
            for value in eqn.params.values()
            for q in (value if isinstance(value, list | tuple) else [value])
            if isinstance(q, jax.extend.core.ClosedJaxpr | jax.extend.core.Jaxpr)
        ]
        if inner:
            for sub in inner:
                jaxpr_sources(sub, counts)
            continue
        counts[""] += 1
        frames = eqn.source_info.traceback.frames if eqn.source_info.traceback else []
        counts.update(
            {f"{f.file_name.rsplit('/rlq/', 1)[1]}:{f.function_name}" for f in frames if "/rlq/" in f.file_name}
        )
    return counts


def profile_summary(log_dir: Path, top: int, min_s: float = 0.25) -> dict:
    """Host events of the profile under ``log_dir``: the ``top`` names by summed duration, and per
    host thread its busy seconds (events at any depth, union of intervals)."""
    import jax

    path = next(log_dir.rglob("*.xplane.pb"))
    data = jax.profiler.ProfileData.from_file(str(path))
    names: dict[str, list[float]] = collections.defaultdict(lambda: [0.0, 0])
    threads = []
    planes = []
    timeline: dict[str, list] = {}
    min_ns = min_s * 1e9
    for plane in data.planes:
        lines = list(plane.lines)
        planes.append([plane.name, len(lines)])
        if not plane.name.startswith("/host"):
            continue
        for line in lines:
            spans = []
            for event in line.events:
                entry = names[event.name[:120]]
                entry[0] += event.duration_ns / 1e9
                entry[1] += 1
                spans.append((event.start_ns, event.end_ns))
            spans.sort()
            long_events = sorted(
                ((e.start_ns, e.duration_ns, e.name[:80]) for e in line.events if e.duration_ns >= min_ns),
                key=lambda x: x[0],
            )
            if long_events:
                timeline[line.name[:40]] = long_events
            busy, end = 0.0, None
            for start, stop in spans:
                if end is None or start > end:
                    busy += stop - start
                    end = stop
                elif stop > end:
                    busy += stop - end
                    end = stop
            if spans:
                threads.append([line.name, round(busy / 1e9, 3), len(spans)])
    threads.sort(key=lambda t: -t[1])
    origin = min((events[0][0] for events in timeline.values()), default=0)
    timeline = {
        thread: [[name, round((st - origin) / 1e9, 3), round(d / 1e9, 3)] for st, d, name in events]
        for thread, events in timeline.items()
    }
    ranked = sorted(names.items(), key=lambda kv: -kv[1][0])[:top]
    return {
        "planes": planes,
        "host_threads_busy_over_0.5s": [t for t in threads if t[1] > 0.5],
        "host_threads": len(threads),
        "top_events": [[name, round(s, 3), n] for name, (s, n) in ranked],
        "timeline_events_over_s": min_s,
        "timeline": timeline,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="lunar_ppo_gpu")
    parser.add_argument("--pair", nargs=2, metavar=("ALGO", "ENV"), help="a pair's recipe instead of --preset")
    parser.add_argument("--machine", default="gpu", choices=("cpu", "gpu"), help="the recipe's machine, with --pair")
    parser.add_argument("--by-source", type=int, default=0, metavar="N", help="HLO instructions per rlq function")
    parser.add_argument("--override", nargs="*", default=[], help="more `rlq train` overrides")
    parser.add_argument("--xla-option", nargs="*", default=[], help="KEY=VALUE for every program")
    parser.add_argument("--program-option", nargs="*", default=[], help="PROGRAM:KEY=VALUE for one program")
    parser.add_argument("--programs", nargs="*", default=list(PROGRAMS), choices=PROGRAMS)
    parser.add_argument("--side-by-side", action="store_true", help="compile as rlq does, side by side")
    parser.add_argument("--profile", action="store_true", help="under jax.profiler (host trace)")
    parser.add_argument("--host-tracer-level", type=int, default=2)
    parser.add_argument("--top", type=int, default=60)
    parser.add_argument("--dump-hlo", type=Path, default=None, help="write each optimized module here (gzip)")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import jax
    from bench_common import CpuSampler, parse_xla_options

    from rlq.config.compose import compose
    from rlq.run.programs.build import build
    from rlq.run.programs.compiler import compile_with, options_from_config
    from rlq.run.programs.compiling import program_options
    from rlq.run.programs.devices import placement
    from rlq.run.programs.keys import seed_keys

    if args.pair:
        algo, env = args.pair
        name, chosen = f"{env}_{algo}_{args.machine}", [f"algo={algo}", f"env={env}", f"machine={args.machine}"]
    else:
        name, chosen = args.preset, [f"experiment={args.preset}"]
    report: dict = {"preset": name, "override": args.override, "xla_option": args.xla_option}
    report["program_option"] = args.program_option
    cfg = compose([*chosen, "compile_cache=null", *args.override])
    options = {**options_from_config(cfg), **parse_xla_options(args.xla_option)}
    per_program: dict[str, dict] = collections.defaultdict(dict)
    for item in args.program_option:
        name, option = item.split(":", 1)
        per_program[name].update(parse_xla_options([option]))
    report["options"] = options
    where = placement(cfg)
    report["device"] = f"{jax.devices()[0].platform} | {jax.devices()[0].device_kind}"
    report["jax"] = jax.__version__
    report["imports_s"] = round(time.perf_counter() - T_START, 2)
    timings: dict[str, dict] = {name: {} for name in args.programs}
    with jax.default_device(where.mesh.devices.flat[0]):
        t = time.perf_counter()
        programs = build(cfg, where)
        report["build_s"] = round(time.perf_counter() - t, 2)
        num_seeds = int(cfg.num_seeds)
        keys = jax.device_put(seed_keys(cfg.seed, num_seeds), where.seeds)
        eval_key = jax.random.fold_in(jax.random.PRNGKey(cfg.seed), 10_007)
        eval_keys = jax.device_put(jax.random.split(jax.random.fold_in(eval_key, 0), num_seeds), where.seeds)
        t = time.perf_counter()
        traced_init = programs.init.trace(keys, programs.hyper_shape)
        state_shape = traced_init.out_info
        trace_init_s = time.perf_counter() - t
        tracers = {
            "init": lambda: traced_init,
            "chunk": lambda: programs.chunk.trace(state_shape, programs.hyper_shape),
            "evaluate": lambda: programs.evaluate.trace(state_shape, eval_keys),
        }
        lowered, jaxprs = {}, {}
        for name in args.programs:
            t = time.perf_counter()
            traced = tracers[name]()
            lowered[name] = traced.lower()
            timings[name]["trace_lower_s"] = round(time.perf_counter() - t + (trace_init_s if name == "init" else 0), 2)
            jaxprs[name] = traced.jaxpr.jaxpr

        def compile_one(name: str):
            t, cpu_before = time.perf_counter(), cpu_seconds()
            # rlq's own per-program options (CPU_OPTIONS, GPU_OPTIONS) under the given ones, as `rlq train` compiles
            compiled = compile_with(
                lowered[name], program_options(name, {**options, **per_program.get(name, {})} or None)
            )
            timings[name]["compile_s"] = round(time.perf_counter() - t, 2)
            if not args.side_by_side:  # the process's CPU time is one program's only when compiled alone
                timings[name]["compile_cpu_s"] = round(cpu_seconds() - cpu_before, 2)
            return compiled

        profile_dir = Path(tempfile.mkdtemp(prefix="xprof_"))
        if args.profile:
            opts = jax.profiler.ProfileOptions()
            opts.host_tracer_level = args.host_tracer_level
            opts.python_tracer_level = 0
            jax.profiler.start_trace(str(profile_dir), profiler_options=opts)
        compiled = {}
        t, cpu_before = time.perf_counter(), cpu_seconds()
        if args.side_by_side:
            with CpuSampler() as cpu, ThreadPoolExecutor(max_workers=len(args.programs)) as pool:
                futures = {name: pool.submit(compile_one, name) for name in args.programs}
                compiled = {name: f.result() for name, f in futures.items()}
            report["side_by_side"] = {"wall_s": round(time.perf_counter() - t, 2), **cpu.summary()}
            report["side_by_side"]["compile_cpu_s"] = round(cpu_seconds() - cpu_before, 2)
            report["side_by_side"]["cpu_series"] = [round(s, 1) for s in cpu.samples[::5]]
        else:
            for name in args.programs:
                with CpuSampler() as cpu:
                    compiled[name] = compile_one(name)
                timings[name].update(cpu.summary())
        if args.profile:
            jax.profiler.stop_trace()
            report["profile"] = profile_summary(profile_dir, args.top)
        for name in args.programs:
            timings[name]["module"] = module_size(compiled[name])
            timings[name]["module"]["stablehlo_lines"] = len(lowered[name].as_text().splitlines())
            equations = jaxpr_sources(jaxprs[name])
            timings[name]["module"]["jaxpr_equations"] = equations.pop("")
            if args.by_source:
                timings[name]["module"]["by_source"] = by_source(compiled[name].as_text(), args.by_source)
                timings[name]["module"]["jaxpr_by_source"] = [[k, v] for k, v in equations.most_common(args.by_source)]
            if args.dump_hlo:
                import gzip

                args.dump_hlo.mkdir(parents=True, exist_ok=True)
                with gzip.open(args.dump_hlo / f"{report['preset']}_{name}.hlo.gz", "wt") as f:
                    f.write(compiled[name].as_text())
    report["programs"] = timings
    report["process_s"] = round(time.perf_counter() - T_START, 2)
    report["load"] = {"start": LOAD_START, "end": [round(load, 2) for load in os.getloadavg()]}
    text = json.dumps(report, indent=1)
    if args.out:
        args.out.write_text(text)
    print(json.dumps({k: v for k, v in report.items() if k != "profile"}, indent=1))


if __name__ == "__main__":
    main()
