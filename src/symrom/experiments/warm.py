"""The learning's compiled routines made ready before a run needs them.

Every model with a term table runs the same numba kernels: the table rollouts and the
refinements' windows, the autoencoder's maps, the guards' timing losses; the aSLIP's rollout
fit runs its compiled RK4. numba compiles them once per installation and keeps them in its disk
cache. On a cold cache a run that simulates its data first (``reproduce``, ``demo``) starts
``start_warm_helper()`` beside its simulation: processes that compile them by doing the work in
small (``warm``), so that the compilation shares the cores with the simulation instead of
holding up the selection, whose worker processes would each compile them at once.
"""

from __future__ import annotations

from symrom.execution import in_disk_cache, start_helper


def routines() -> list:
    """The numba dispatchers ``warm`` makes ready."""
    from symrom.baselines.compiled import aslip_rk4
    from symrom.compiled import routines as compiled_routines
    from symrom.learn.compiled import timing_losses

    return [*compiled_routines(), timing_losses, aslip_rk4]


def cold() -> bool:
    """Whether numba's disk cache lacks a build of any of ``routines()``."""
    return not all(in_disk_cache(d) for d in routines())


def warm(windows: bool = True) -> None:
    """Compile (or load) ``routines()`` as a run calls them: a selection of one candidate on a
    small planted dataset, its evaluation at both horizons, the aSLIP fitted on rollouts of
    spring-mass hops, then (``windows``) the refinements' window kernel
    (``compiled.warm_windows``). Writes nothing but numba's cache."""
    from symrom.baselines.aslip import ASlip
    from symrom.compiled import warm_windows
    from symrom.evaluate.metrics import evaluate_model
    from symrom.experiments.select import SelectionConfig, select
    from symrom.rollout.integrate import RolloutOptions
    from symrom.testing import make_planted_dataset, make_slip_dataset

    ds, _ = make_planted_dataset(n_jumps=5, n_samples=120, seed=1)
    sel = select(ds, SelectionConfig(encoders=("standardised",), latent_dims=(2,), libraries=("poly1+inputs",),
                                     thresholds=(1e-2,), refine_top=0))
    if sel.model is not None:
        evaluate_model(sel.model, ds, "test", (None, 0.1), RolloutOptions("rk4"))
    slip, truth = make_slip_dataset(n_jumps=3, n_samples=100)
    aslip = ASlip.fit(slip, m=truth["m"], objective="rollout")
    evaluate_model(aslip, slip, "test", (None, 0.1), RolloutOptions("rk4"))
    if windows:
        warm_windows()


def start_warm_helper():
    """On a cold cache (``cold``), two processes: one compiling the refinements' window kernel
    (``compiled.start_windows_helper``; the longest to compile, needed last: a selection's
    refinements wait for it), and one running the rest of ``warm``, returned (a
    ``subprocess.Popen``) for the first selection to wait for. None on a filled cache, or if no
    process can be started."""
    from symrom.compiled import start_windows_helper

    if not cold():
        return None
    start_windows_helper()
    return start_helper("from symrom.experiments.warm import warm; warm(windows=False)")
