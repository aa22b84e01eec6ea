"""Benchmark of rollouts of one learned model, every path side by side in one process (not a test).

The model: l = 2, p = 1 (the paper's library, 15 candidates), trained with the
exact solver on the planted dataset of ``bench_learner.py`` (120 jumps x 800
samples, block embedding, seed 0). Paths, all integrating the same latent
states with the inputs and the phase held over each 2 ms sample:

- LSODA with the NumPy right-hand side (``backend="numpy"``, odeint's default
  tolerances), with the model's compiled right-hand side (``"generated"``), and
  compiled as a whole (``lsoda_solver="numbalsoda"``: numbalsoda's LSODA called
  from a numba loop with the generated right-hand side as a C callback; needs
  ``pip install 'symrom[lsoda]'``), each compared with the first at the same
  tolerances (``same_as_scipy_*``);
- RK4 (2 steps per sample) in NumPy, by the compiled term-table kernel
  (``"table"``) and by the model's generated code (``"generated"``);
- RK4 by the exported C (``symrom export --to c``, compiled with the system's
  ``cc -O2``, driven by a small C loop over the jumps called once via ctypes);
- PySINDy's ``simulate`` on the same model (one ``SINDy`` per phase with the
  model's coefficients, LSODA at its default rtol = atol = 1e-12, once per
  sample interval, as symrom's LSODA, so that the input is held), the peer.
  It needs ``pip install 'symrom[bench]'``; it runs on ``--peer-jumps`` jumps.

Times are of the integration alone (the encoded states in, for the RK4 paths
padded to the longest jump as ``rollout`` pads them; the latent paths out), the
same work for every path; for symrom's RK4 paths the whole ``rollout`` call
(set-up, encoding, padding, decoding) is timed as well. Medians over repeated
runs; the first call of each path (JIT compilation, or ``cc``) is reported
apart. Drift: the largest |latent state - reference| over all samples, the
reference being LSODA with rtol = atol = 1e-10 (at odeint's default tolerance
LSODA's own error is ~1e-6 over a jump). Prints a Markdown table and writes
JSON.

    python benchmarks/bench_rollout.py --out benchmarks/results/rollout.json
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

# Compile the numba kernels afresh, so that their compilation time is measured (not a
# load from the on-disk cache of an earlier run).
os.environ.setdefault("NUMBA_CACHE_DIR", tempfile.mkdtemp(prefix="symrom-bench-numba-"))

import numpy as np
from provenance import provenance

from symrom import compiled
from symrom.export import export
from symrom.learn.training import TrainConfig, train
from symrom.rollout import compiled_lsoda
from symrom.rollout.integrate import (
    RolloutOptions,
    integrate_rk4,
    integrate_system,
    pad_edge,
    reset_mask,
    rollout,
)
from symrom.testing import make_planted_dataset

REFERENCE_TOL = 1e-10  # LSODA's rtol and atol for the drift reference

C_DRIVER = r"""
#include <math.h>
#include "symrom_model.h"
/* J jumps (padded to n_max samples) from their true start, reset to the truth where
   resets[k]; the semantics of symrom.rollout.integrate.integrate_rk4. */
void bench_rollout(int J, int n_max, const double *x_true, const double *v_true, const double *nu,
                   const long long *phase, const long long *lens, const unsigned char *resets, double dt,
                   int substeps, const double *limit, double *X, double *V, long long *div_at) {
    const int l = SYMROM_LATENT_DIM;
    double s[2 * SYMROM_LATENT_DIM];
    double h = dt / substeps;
    for (int j = 0; j < J; j++) {
        div_at[j] = -1;
        for (long long k = 0; k < lens[j]; k++) {
            long long o = ((long long)j * n_max + k) * l;
            if (k == 0 || resets[k])
                for (int d = 0; d < l; d++) { s[d] = x_true[o + d]; s[l + d] = v_true[o + d]; }
            int ok = 1;
            for (int d = 0; d < 2 * l; d++)
                if (!(fabs(s[d]) <= limit[j * 2 * l + d])) ok = 0;
            if (!ok) { div_at[j] = k; break; }
            for (int d = 0; d < l; d++) { X[o + d] = s[d]; V[o + d] = s[l + d]; }
            if (k == lens[j] - 1) break;
            for (int i = 0; i < substeps; i++)
                symrom_rk4_step((int)phase[(long long)j * n_max + k], s, nu + o, h);
        }
    }
}
"""


def timed(fn, runs: int) -> dict:
    """First call and the median of ``runs`` further calls: wall s, and CPU s of this
    process (what an otherwise idle core gives when other jobs share the machine)."""
    t0 = time.perf_counter()
    fn()
    first = time.perf_counter() - t0
    times, cpu = [], []
    for _ in range(runs):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return {"first_s": first, "median_s": statistics.median(times), "runs": times,
            "cpu_median_s": statistics.median(cpu), "cpu_runs": cpu}


class CRollout:
    """The exported C of ``model`` with the driver above, compiled by ``cc`` into a shared library."""

    def __init__(self, model, folder: Path):
        cc = shutil.which("cc") or shutil.which("gcc")
        if cc is None:
            raise RuntimeError("no C compiler (cc)")
        files = export(model, "c", folder)
        driver = folder / "driver.c"
        driver.write_text(C_DRIVER)
        so = folder / "model.so"
        self.flags = ["-std=c99", "-O2", "-shared", "-fPIC"]
        t0 = time.perf_counter()
        subprocess.run([cc, *self.flags, "-I", str(folder), "-o", str(so), str(files[1]), str(driver), "-lm"],
                       check=True, capture_output=True)
        self.compile_s = time.perf_counter() - t0
        self.lib = ctypes.CDLL(str(so))
        self.fn = self.lib.bench_rollout
        self.fn.restype = None

    def __call__(self, x_true, v_true, drive, lens, resets, limit, dt, substeps):
        J, n_max, l = x_true.shape
        X, V = np.full((J, n_max, l), np.nan), np.full((J, n_max, l), np.nan)
        div_at = np.full(J, -1, dtype=np.int64)
        arrays = [np.ascontiguousarray(x_true, dtype=float), np.ascontiguousarray(v_true, dtype=float),
                  np.ascontiguousarray(drive["nu"], dtype=float), np.ascontiguousarray(drive["phase"], dtype=np.int64),
                  np.ascontiguousarray(lens, dtype=np.int64), np.ascontiguousarray(resets, dtype=np.uint8)]
        lim = np.ascontiguousarray(np.broadcast_to(limit, (J, 2 * l)), dtype=float)
        ptr = [a.ctypes.data_as(ctypes.c_void_p) for a in arrays]
        self.fn(ctypes.c_int(J), ctypes.c_int(n_max), *ptr, ctypes.c_double(dt), ctypes.c_int(substeps),
                lim.ctypes.data_as(ctypes.c_void_p), X.ctypes.data_as(ctypes.c_void_p),
                V.ctypes.data_as(ctypes.c_void_p), div_at.ctypes.data_as(ctypes.c_void_p))
        return X, V, div_at


class PeerRollout:
    """PySINDy's ``simulate`` on the model: one ``SINDy`` per phase whose coefficients are the
    model's, the first-order state y = [xi, dxi] with the inputs nu as controls."""

    def __init__(self, model):
        import pysindy as ps

        self.version = ps.__version__
        l = self.l = model.latent_dim
        if model.library.feature_names != model.library.__class__.standard(l, 1).feature_names:
            raise ValueError("the peer is set up for the paper's library with p = 1")
        rng = np.random.default_rng(0)
        y, u = rng.uniform(-2, 2, (64, 2 * l)), rng.uniform(-2, 2, (64, l))
        ours = model.library.transform(y[:, :l], y[:, l:], u)
        self.models = []
        for k in range(len(model.phase_names)):
            lib = ps.GeneralizedLibrary(
                [ps.PolynomialLibrary(degree=1, include_bias=True), ps.FourierLibrary(n_frequencies=1),
                 ps.IdentityLibrary()],
                inputs_per_library=[list(range(2 * l)), list(range(2 * l)), list(range(2 * l, 3 * l))])
            sm = ps.SINDy(feature_library=lib, optimizer=ps.STLSQ(threshold=0.0))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                sm.fit(y, t=0.002, u=u, x_dot=rng.standard_normal(y.shape))
            theirs = np.asarray(sm.feature_library.transform([np.c_[y, u]])[0])
            # Each of PySINDy's columns is one of the model's terms: match them by value.
            match = [int(np.flatnonzero(np.all(np.abs(ours - theirs[:, [c]]) < 1e-12, axis=0))[0])
                     for c in range(theirs.shape[1])]
            coef = np.zeros((2 * l, theirs.shape[1]))
            for c, o in enumerate(match):
                coef[l:, c] = model.Xi[k][o]
                if 1 + l <= o < 1 + 2 * l:  # the term dxi_i: d(xi_i)/dt = dxi_i
                    coef[o - 1 - l, c] = 1.0
            sm.optimizer.coef_ = coef
            check = sm.predict(y, u=u)[:, l:]
            np.testing.assert_allclose(check, model.latent_acceleration(
                y[:, :l], y[:, l:], u, np.full(len(y), k)), rtol=1e-10, atol=1e-10)
            self.models.append(sm)

    def __call__(self, x_true, v_true, drive, lens, resets, dt):
        """Per jump the path (n, 2l) from the true start, reset where ``resets``."""
        out = []
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for j, n in enumerate(lens):
                nu, ph = drive["nu"][j], drive["phase"][j]
                Y = np.empty((n, 2 * self.l))
                y = np.r_[x_true[j, 0], v_true[j, 0]]
                for k in range(n):
                    if resets[k]:
                        y = np.r_[x_true[j, k], v_true[j, k]]
                    Y[k] = y
                    if k < n - 1:
                        y = self.models[ph[k]].simulate(y, np.array([k * dt, (k + 1) * dt]),
                                                        u=lambda _t, w=nu[k]: w)[-1]
                out.append(Y)
        return out


def drift(paths: list[np.ndarray], ref: list[np.ndarray]) -> float:
    """Largest |path - reference| over the samples both have (finite)."""
    worst = 0.0
    for a, b in zip(paths, ref):
        d = np.abs(a - b)
        d = d[np.isfinite(d)]
        worst = max(worst, float(d.max()) if d.size else 0.0)
    return worst


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jumps", type=int, default=120)
    ap.add_argument("--samples", type=int, default=800)
    ap.add_argument("--runs", type=int, default=7, help="timed runs of the fast paths")
    ap.add_argument("--slow-runs", type=int, default=3, help="timed runs of the LSODA paths")
    ap.add_argument("--single-runs", type=int, default=101, help="timed runs of the fast paths on one jump")
    ap.add_argument("--peer-jumps", type=int, default=1,
                    help="jumps PySINDy simulates (about two minutes each); 0: no peer")
    ap.add_argument("--substeps", type=int, default=2)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    wall0 = time.perf_counter()

    ds, _ = make_planted_dataset(args.jumps, args.samples, embedding="block", noise=1e-4, seed=0)
    model = train(ds, TrainConfig())
    jumps = np.arange(ds.n_jumps)
    res: dict = {
        "dataset": {"jumps": args.jumps, "samples_per_jump": args.samples, "dt": ds.dt},
        "model": {"latent_dim": model.latent_dim, "candidates": model.library.n_features,
                  "active_terms": int((model.Xi != 0).sum()),
                  "active_terms_per_phase": {n: int((model.Xi[k] != 0).any(1).sum())
                                             for k, n in enumerate(model.phase_names)}},
        "substeps": args.substeps, "reference": f"lsoda, rtol = atol = {REFERENCE_TOL:g}",
        "machine": {"python": platform.python_version(), "cpu": platform.processor() or platform.machine(),
                    "numpy": np.__version__},
        "horizons": {}, "single_jump": {},
        "compiled_lsoda": "numbalsoda" if compiled_lsoda.available() else
                          "not run: " + compiled_lsoda.INSTALL_HINT,
    }
    tmp = Path(tempfile.mkdtemp(prefix="symrom-bench-"))
    c_model = None
    try:
        c_model = CRollout(model, tmp)
        res["compile_s"] = {"c": c_model.compile_s, "c_flags": " ".join(c_model.flags)}
    except (RuntimeError, subprocess.CalledProcessError) as e:
        res["compile_s"] = {"c": None, "c_error": str(e)}
    peer = None
    if args.peer_jumps > 0:
        try:
            peer = PeerRollout(model)
            res["peer"] = {"pysindy": peer.version, "jumps": min(args.peer_jumps, args.jumps),
                           "integrator": "solve_ivp LSODA, rtol = atol = 1e-12, per sample interval"}
        except ImportError:
            res["peer"] = {"error": "pysindy is not installed (pip install 'symrom[bench]')"}

    def paths(sel: np.ndarray, reset: float | None):
        """{name: (integration callable -> (Xs, Vs, div_at), end-to-end callable or None, kind)}."""
        sysm = model.rollout_system(ds, sel)
        lens = np.array([x.shape[0] for x in sysm.x])
        xp, vp = pad_edge(sysm.x), pad_edge(sysm.v)
        drive = {k: pad_edge(d) for k, d in sysm.drive.items()}
        resets = reset_mask(int(lens.max()), reset, ds.dt)
        limit = 50.0 * sysm.scale

        def opts(method, backend, **kw):
            return RolloutOptions(method, reset, substeps=args.substeps, backend=backend, **kw)

        def system(o):
            return lambda: integrate_system(sysm, o, ds.dt)

        def whole(o):
            return lambda: rollout(model, ds, sel, o)

        def padded(fn):
            def run():
                X, V, div = fn(xp, vp, drive, lens, resets, limit, ds.dt, args.substeps)
                return [X[j, :n] for j, n in enumerate(lens)], [V[j, :n] for j, n in enumerate(lens)], div
            return run

        def numpy_rk4(x_true, v_true, drv, lens, resets, limit, dt, substeps):
            Xs, Vs, div = integrate_rk4(lambda k, xs, vs: sysm.acceleration(
                {n: a[:, k] for n, a in drv.items()}, xs, vs), x_true, v_true, lens, resets, limit, dt, substeps)
            return pad_edge(Xs), pad_edge(Vs), div

        # The RK4 integrators on the padded arrays, as rollout() calls them (its padding apart).
        out = {
            "lsoda_numpy": (system(opts("lsoda", "numpy")), None, "lsoda"),
            "lsoda_generated": (system(opts("lsoda", "generated")), None, "lsoda"),
            **({"lsoda_compiled": (system(opts("lsoda", "generated", lsoda_solver="numbalsoda")), None, "lsoda")}
               if compiled_lsoda.available() else {}),
            "rk4_numpy": (padded(numpy_rk4), whole(opts("rk4", "numpy")), "rk4"),
            "rk4_table": (padded(sysm.compiled), whole(opts("rk4", "table")), "rk4"),
            "rk4_generated": (padded(compiled.generated(model.dynamics()).integrator), whole(opts("rk4", "generated")),
                              "rk4"),
        }
        if c_model is not None:
            out["rk4_c"] = (padded(c_model), None, "rk4")
        ref = integrate_system(sysm, opts("lsoda", "generated", rtol=REFERENCE_TOL, atol=REFERENCE_TOL), ds.dt)
        return out, ref, (sysm, lens, xp, vp, drive, resets)

    labels = {"lsoda_numpy": "LSODA, NumPy right-hand side", "lsoda_generated": "LSODA, compiled right-hand side",
              "lsoda_compiled": "LSODA compiled (numbalsoda)",
              "rk4_numpy": "RK4, NumPy", "rk4_table": "RK4, compiled term table (`table`)",
              "rk4_generated": "RK4, generated code", "rk4_c": "RK4, exported C", "peer": "PySINDy `simulate` (peer)"}

    def measure(sel: np.ndarray, reset: float | None, runs: int, slow_runs: int, n_peer: int) -> dict:
        fns, ref, (_sysm, lens, xp, vp, drive, resets) = paths(sel, reset)
        steps = int((lens - 1).sum()) * args.substeps
        rows, scipy_paths = {}, None
        for name, (integ, end_to_end, kind) in fns.items():
            n_runs = slow_runs if kind == "lsoda" or name == "rk4_numpy" else runs
            t = timed(integ, n_runs)
            Xs, Vs, div = integ()
            row = {"integration": t, "drift_xi": drift(Xs, ref[0]), "drift_dxi": drift(Vs, ref[1]),
                   "diverged": int((div >= 0).sum()), "diverged_at_matches_reference":
                   bool(np.array_equal(div, ref[2]))}
            if name == "lsoda_numpy":
                scipy_paths = (Xs, Vs)
            elif kind == "lsoda":  # the same solver at the same tolerances
                row["same_as_scipy_xi"], row["same_as_scipy_dxi"] = drift(Xs, scipy_paths[0]), drift(Vs, scipy_paths[1])
            if kind == "rk4":
                row["rk4_steps_per_s"] = steps / t["cpu_median_s"]
                row["rk4_steps_per_wall_s"] = steps / t["median_s"]
            if end_to_end is not None and kind == "rk4":  # LSODA's call is its integration
                row["rollout_call"] = timed(end_to_end, n_runs)
            rows[name] = row
            print(f"  {name}: {t['median_s']:.3g} s, CPU {t['cpu_median_s']:.3g} s (first call {t['first_s']:.3g} s)",
                  file=sys.stderr, flush=True)
        if peer is not None and n_peer > 0:
            k = min(n_peer, len(lens))
            t0, c0 = time.perf_counter(), time.process_time()
            Y = peer(xp[:k], vp[:k], {n: d[:k] for n, d in drive.items()}, lens[:k], resets, ds.dt)
            secs, cpu = time.perf_counter() - t0, time.process_time() - c0
            rows["peer"] = {"jumps": k, "integration": {"median_s": secs, "runs": [secs], "cpu_median_s": cpu,
                                                        "cpu_runs": [cpu]},
                            "drift_xi": drift([y[:, :model.latent_dim] for y in Y], ref[0][:k]),
                            "drift_dxi": drift([y[:, model.latent_dim:] for y in Y], ref[1][:k])}
            print(f"  peer ({k} jumps): {secs:.3g} s", file=sys.stderr, flush=True)
        base = {n: rows[n]["integration"]["cpu_median_s"] for n in ("lsoda_numpy", "rk4_numpy")}
        for row in rows.values():  # ratios of CPU time, per jump
            per_jump = row["integration"]["cpu_median_s"] * len(lens) / row.get("jumps", len(lens))
            row["speedup_vs_lsoda"] = base["lsoda_numpy"] / per_jump
            row["speedup_vs_numpy_rk4"] = base["rk4_numpy"] / per_jump
        return {"jumps": len(lens), "samples": int(lens.sum()), "rk4_steps": steps, "paths": rows}

    for reset in (None, 0.1):
        key = "full" if reset is None else "0.1"
        print(f"{args.jumps} jumps, horizon {key}", file=sys.stderr, flush=True)
        res["horizons"][key] = measure(jumps, reset, args.runs, args.slow_runs,
                                       args.peer_jumps if args.peer_jumps > 1 else 0)
    print("one jump, full horizon", file=sys.stderr, flush=True)
    res["single_jump"] = measure(np.array([0]), None, args.single_runs, args.slow_runs,
                                 1 if args.peer_jumps >= 1 else 0)
    res["compile_s"]["generated"] = compiled.compile_seconds(model.dynamics())
    res["wall_time_s"] = time.perf_counter() - wall0
    shutil.rmtree(tmp, ignore_errors=True)

    print(f"\nl = {model.latent_dim}, p = 1, {res['model']['active_terms']} active coefficients; "
          f"RK4 with {args.substeps} steps per 2 ms sample; drift against LSODA at rtol = atol = "
          f"{REFERENCE_TOL:g}; times are medians of the integration alone (wall, and CPU of this process); "
          f"steps/s and ratios by CPU time.\n")
    print("| path | horizon | jumps | median wall | median CPU | RK4 steps/s | vs LSODA | vs NumPy RK4 "
          "| max drift xi / dxi | first call | `rollout()` median |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")

    def fmt_t(s: float) -> str:
        return f"{s * 1e3:.3g} ms" if s < 1 else f"{s:.3g} s"

    for key, block in [*res["horizons"].items(), ("one jump", res["single_jump"])]:
        for name, row in block["paths"].items():
            t = row["integration"]
            steps = f"{row['rk4_steps_per_s']:.3g}" if "rk4_steps_per_s" in row else "-"
            whole = fmt_t(row["rollout_call"]["median_s"]) if "rollout_call" in row else "-"
            first = fmt_t(t["first_s"]) if "first_s" in t else "-"
            print(f"| {labels[name]} | {key} | {row.get('jumps', block['jumps'])} | {fmt_t(t['median_s'])} "
                  f"| {fmt_t(t['cpu_median_s'])} | {steps} "
                  f"| {row['speedup_vs_lsoda']:.3g}x | {row['speedup_vs_numpy_rk4']:.3g}x "
                  f"| {row['drift_xi']:.1e} / {row['drift_dxi']:.1e} | {first} | {whole} |")
    for key, block in [*res["horizons"].items(), ("one jump", res["single_jump"])]:
        for name, row in block["paths"].items():
            if "same_as_scipy_xi" in row:
                print(f"\n{labels[name]}, {key}: largest |difference| from SciPy's LSODA at the same tolerances "
                      f"{row['same_as_scipy_xi']:.1e} (xi) / {row['same_as_scipy_dxi']:.1e} (dxi).", end="")
    print()
    c = res["compile_s"]
    print(f"\nCompilation: generated code {c['generated']:.2f} s per model; exported C "
          f"{c['c'] if c['c'] is None else f'{c[chr(99)]:.2f} s'} (cc {c.get('c_flags', '')}); the term-table "
          f"kernel once per installation (its first call above). Wall time {res['wall_time_s']:.0f} s.")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps({**provenance(), **res}, indent=1))


if __name__ == "__main__":
    main()
