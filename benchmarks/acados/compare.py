"""aerorelay's C step against acados' SQP_RTI on the same recorded steps, alternating, on one pinned core.

Runs in aerorelay's environment; acados runs in its own (`setup.sh`), called as `ACADOS_PYTHON peer.py`:

    python benchmarks/acados/compare.py scenarios/nominal_tilted.toml --out bench-acados \
        --acados-python ~/acados-env/bin/python --rounds 3
    python benchmarks/acados/compare.py scenarios/nominal_tilted.toml --chain 5 --relay r3 --out bench-chain ...

What it does: writes the relay's C tree (`aerorelay codegen`, no C planner: every step's stage parameters recorded),
flies the scenario recording that relay's steps (the Python controller's commands beside), builds the tree's
`build/bench` (`make SIMD=1` where this machine's engine runs BLASFEO's AVX2 kernels) and acados' solver for each
`--cond-n` from the tree's `manifest.json` (`peer.py`), then, `--rounds` times, replays the recording through `ar_step`
(`build/bench`, the whole step) and through each acados configuration (acados' own `time_tot`), the order rotated each
round, every process pinned to `--core`. Prints per round mean / p50 / p99 (ms), acados' QP iterations and failures,
the ratios of aerorelay's step to the better acados configuration (at the mean: the lower mean; at the p99: the lower
p99) and whether the target (both ratios <= 0.8: >= 20% faster) holds in every round; writes `compare.json` into --out.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
STATS = ("mean", "p50", "p95", "p99", "max")


def stats_ms(ns: np.ndarray) -> dict:
    ms = np.asarray(ns, float) * 1e-6
    return {"mean": float(ms.mean()), "p50": float(np.median(ms)), "p95": float(np.percentile(ms, 95)),
            "p99": float(np.percentile(ms, 99)), "max": float(ms.max())}


def pinned(core: int):
    return lambda: os.sched_setaffinity(0, {core})


def run(cmd: list[str], core: int | None = None, **kw) -> subprocess.CompletedProcess:
    r = subprocess.run(cmd, capture_output=True, text=True, preexec_fn=pinned(core) if core is not None else None, **kw)
    if r.returncode != 0:
        raise SystemExit(f"failed ({r.returncode}): {' '.join(cmd)}\n{r.stderr[-2000:]}")
    return r


def scenario(args):
    from aerorelay.assembly import load_scenario
    from aerorelay.assembly.load import parse_sets
    from aerorelay.experiments.chains import long_chain

    updates = parse_sets(args.set or [])
    if args.duration is not None:
        updates["sim.duration_s"] = args.duration
    if args.chain:
        return long_chain(args.scenario, args.chain, args.length, updates=updates)
    return load_scenario(args.scenario, updates)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenario", type=Path)
    ap.add_argument("--out", type=Path, required=True, help="a new or empty folder")
    ap.add_argument("--acados-python", required=True, help="the Python of the acados environment (setup.sh)")
    ap.add_argument("--relay", default=None, help="the relay of a network (required there)")
    ap.add_argument("--chain", type=int, default=0, help="fly a generated chain of this many relays (aerorelay bench --chain's)")
    ap.add_argument("--length", type=float, default=250.0, help="--chain: its length (m)")
    ap.add_argument("--set", action="append", help="a scenario setting, as aerorelay's --set")
    ap.add_argument("--duration", type=float, default=None, help="seconds of the mission to record (default: all)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--cond-n", default="10,15", help="acados' partial condensing horizons to compare (comma-separated)")
    ap.add_argument("--core", type=int, default=None, help="the core every timed process is pinned to (default: the last)")
    ap.add_argument("--blasfeo", default=None,
                    help="a BLASFEO library (e.g. acados' libblasfeo.so, built for Haswell): also time the tree with "
                         "BLASFEO's calls resolved to it (LD_PRELOAD, a SIMD=0 build; 'c_blasfeo')")
    a = ap.parse_args(argv)
    from aerorelay import api

    out = a.out
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise SystemExit(f"--out: {out} exists and is not an empty folder")
    conds = [int(c) for c in a.cond_n.split(",")]
    core = a.core if a.core is not None else max(os.sched_getaffinity(0))
    sc = scenario(a)  # bad input fails here, before any work
    out.mkdir(parents=True, exist_ok=True)
    steps = out / "steps.csv"
    print(f"recording {sc.name}: {sc.duration_s:g} s of flight", flush=True)
    summary = api.codegen(sc, out / "tree", record=steps, planner=False, relay=a.relay)
    manifest = json.loads((out / "tree" / "manifest.json").read_text())
    simd = int(bool(manifest["simd_here"]))
    print(f"building build/bench (make SIMD={simd}) and acados' solvers (cond_N {', '.join(map(str, conds))})", flush=True)
    run(["make", "-s", "-C", str(out / "tree"), f"SIMD={simd}", "build/bench"])
    if a.blasfeo:  # the same tree, HPIPM's and the tree's BLASFEO calls resolved to the given library
        if not Path(a.blasfeo).is_file():
            raise SystemExit(f"--blasfeo: no such file: {a.blasfeo}")
        run(["cp", "-r", str(out / "tree"), str(out / "tree_blasfeo")])
        run(["make", "-s", "-C", str(out / "tree_blasfeo"), "clean"])
        run(["make", "-s", "-C", str(out / "tree_blasfeo"), "SIMD=0", "build/bench", "build/replay"])
    for n in conds:
        run([a.acados_python, str(HERE / "peer.py"), "build", str(out / "tree"), str(out / f"acados_{n}"), "--cond-n", str(n)])
    expected = np.loadtxt(f"{steps}.expected", delimiter=",", ndmin=2)
    res: dict = {"scenario": sc.name, "relay": summary["relay"], "steps": int(len(expected)), "core": core, "simd": bool(simd),
                 "brake_law_steps": int(expected[:, 0].sum()), "rounds": []}
    who = ["c"] + [f"acados_{n}" for n in conds] + (["c_blasfeo"] if a.blasfeo else [])
    acados = [f"acados_{n}" for n in conds]
    if a.blasfeo:  # what the library does to the commands: the tree's replay against Python's
        env = {**os.environ, "LD_PRELOAD": str(Path(a.blasfeo).resolve())}
        u = np.array([[float(v) for v in line.split(",")[5:]] for line in
                      run([str(out / "tree_blasfeo" / "build" / "replay"), str(steps)], env=env).stdout.splitlines()])
        du = np.abs(u - expected[:, 1:])
        res["blasfeo"] = {"library": str(a.blasfeo), "command_difference_hz_s": {
            "mean": float(du.mean()), "median": float(np.median(du)), "max": float(du.max())}}
    for r in range(a.rounds):
        order = who[r % len(who):] + who[: r % len(who)]
        rnd: dict = {}
        for w in order:
            print(f"round {r + 1}/{a.rounds}: {w}", flush=True)
            if w in ("c", "c_blasfeo"):
                tree, env = (out / "tree", None) if w == "c" else \
                    (out / "tree_blasfeo", {**os.environ, "LD_PRELOAD": str(Path(a.blasfeo).resolve())})
                ns = np.array([[float(v) for v in line.split(",")] for line in
                               run([str(tree / "build" / "bench"), str(steps), "1"], core, env=env).stdout.splitlines()])
                rnd[w] = {"step_ms": stats_ms(ns[:, 2]), "preparation_ms": stats_ms(ns[:, 3]), "feedback_ms": stats_ms(ns[:, 4]),
                            "qp_iterations_mean": float(ns[:, 5].mean()), "qp_iterations_max": int(ns[:, 5].max())}
            else:
                times = out / f"{w}.csv"
                run([a.acados_python, str(HERE / "peer.py"), "replay", str(out / "tree"), str(out / w), str(steps),
                     "--cond-n", w.split("_")[1], "--out", str(times)], core)
                t = np.loadtxt(times, delimiter=",", ndmin=2)
                du = np.abs(t[:, 5:] - expected[:, 1:])
                rnd[w] = {"step_ms": stats_ms(t[:, 2]), "qp_iterations_mean": float(t[:, 3].mean()),
                          "qp_iterations_max": int(t[:, 3].max()), "failures": int((t[:, 4] != 0).sum()),
                          "command_difference_hz_s": {"mean": float(du.mean()), "median": float(np.median(du)),
                                                      "max": float(du.max())}}
        best_mean = min(rnd[w]["step_ms"]["mean"] for w in acados)
        best_p99 = min(rnd[w]["step_ms"]["p99"] for w in acados)
        for c in ("c", "c_blasfeo"):
            if c in rnd:
                rnd[f"ratio_mean{c[1:]}"] = rnd[c]["step_ms"]["mean"] / best_mean
                rnd[f"ratio_p99{c[1:]}"] = rnd[c]["step_ms"]["p99"] / best_p99
        res["rounds"].append(rnd)
    res["target_met_every_round"] = all(r["ratio_mean"] <= 0.8 and r["ratio_p99"] <= 0.8 for r in res["rounds"])
    if a.blasfeo:
        res["target_met_every_round_blasfeo"] = all(r["ratio_mean_blasfeo"] <= 0.8 and r["ratio_p99_blasfeo"] <= 0.8
                                                    for r in res["rounds"])
    (out / "compare.json").write_text(json.dumps(res, indent=2) + "\n")
    print(f"\n{sc.name}, relay {res['relay']}: {res['steps']} recorded steps ({res['brake_law_steps']} on the brake law), "
          f"core {core}, SIMD={simd}")
    print(f"{'round / who':<24}" + "".join(f"{s:>9}" for s in STATS) + "   QP iterations / failures")
    for i, rnd in enumerate(res["rounds"], 1):
        for w in who:
            v = rnd[w]["step_ms"]
            extra = f"   {rnd[w]['qp_iterations_mean']:.2f} / {rnd[w].get('failures', '-')}"
            print(f"{f'{i}: {w}':<24}" + "".join(f"{v[s]:9.3f}" for s in STATS) + extra)
        print(f"{f'{i}: C / best acados':<24}mean {rnd['ratio_mean']:.2f}, p99 {rnd['ratio_p99']:.2f}")
        if a.blasfeo:
            print(f"{f'{i}: C (--blasfeo) / best':<24}mean {rnd['ratio_mean_blasfeo']:.2f}, p99 {rnd['ratio_p99_blasfeo']:.2f}")
    d = res["rounds"][0][acados[0]]["command_difference_hz_s"]
    print(f"acados' commands against aerorelay's (cond_N {conds[0]}): mean {d['mean']:.3g}, median {d['median']:.3g}, "
          f"max {d['max']:.3g} Hz/s")
    print(f"target (C step >= 20% faster than the better acados at the mean and the p99, every round): "
          f"{'met' if res['target_met_every_round'] else 'not met'}")
    if a.blasfeo:
        d = res["blasfeo"]["command_difference_hz_s"]
        print(f"with --blasfeo {a.blasfeo}: {'met' if res['target_met_every_round_blasfeo'] else 'not met'}; its commands "
              f"against Python's (CasADi's BLASFEO): mean {d['mean']:.3g}, median {d['median']:.3g}, max {d['max']:.3g} Hz/s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
