"""The paper's experiments end to end, into one run directory.

Layout of ``DIR`` (every step is skipped when its output exists, so an
interrupted run resumes where it stopped and datasets are never regenerated):

    data/go1_sim.h5, a1_sim.h5, go1_noisy.h5, go1_randomized.h5, a1_randomized.h5,
         go1_proxy.h5, go1_proxy_mujoco.h5, a1_proxy_mujoco.h5  simulated datasets (the three
               sim-to-real targets logged with a real robot's log faults)
         <target>.csv, <target>_repaired.h5                       each target as a log, and
               imported through the repair from physics (what sim-to-real fits and judges)
    <exp>/     model.json (the selected model), eval/, selection/ (selection.json, cells/),
               paper_defaults/ (model.json, eval/),
               aslip/, aslip_rollout/, newton/, newton_fitted/ (metrics.json, table.md, params.json)
    go1_sim/solvers/{exact,adam}/ (model.json, eval/)
    sources/<noisy|randomized|a1_randomized>/<refined|exact>/model.json   sim-to-real sources,
               trained on the noisy and the domain-randomised Go1 with the settings selected on
               SIM Go1, on the domain-randomised A1 froggy with those selected on SIM A1
    go1_proxy/, go1_proxy_mujoco/, a1_proxy_mujoco/   sim-to-real targets (the Go1 proxy in
               PyBullet and MuJoCo, an A1 froggy with a real froggy's long push in MuJoCo):
               model.json (the candidate chosen on the target's val jumps), finetune_choice.json,
               eval/, sources_eval/<source>/<variant>/ (sources as trained, on the repaired
               jumps), sources_eval_logged/ (the table's source on the jumps as logged),
               fine_tuned/ (the default fine-tuning, checked on val), target_alone/ (trained on
               the target's repaired train jumps alone)
    sweep/     sweep.json, cells/, encoders/W_e_l<k>.json
    summary.json   experiments, sweep, sim2real, run, and ``manifest``: every experiment
                   with its role and files, which the report renders

Every ``model.json`` has its ``equations.txt`` beside it (``write_model_files``).

Experiments, one module each: the SIM experiments (``sim``: SIM Go1 pronking, SIM A1 froggy,
phases contact / partial / flight), each with its baselines beside it (``baselines``: aSLIP
fitted to acceleration residuals and to rollouts, Newton on the measured force as it is and
with fitted gains), both solvers on SIM Go1 (``solvers``), the latent-dimension trade-off on
SIM Go1 (``sweep``) and sim-to-real on three targets (``sim2real``: train on the noisy and on the
domain-randomised Go1, or the domain-randomised A1 froggy; import the target's logs through the
repair; fine-tune on its training jumps, choose on its val jumps, evaluate on its test jumps
beside the source as is, on the jumps as logged and repaired, and a model of the target's jumps
alone).
``config`` says what a run holds, ``steps`` the resumable steps they share, ``run`` runs them
in order and writes the summary.

Every SIM model's settings are chosen by the validation selection
(``symrom.experiments.select``: encoder, latent dimension, library, sparsity,
refinement; the test split is read only by the evaluation). The paper's
defaults (its latent dimension, encoder over all 18 components,
decoded-acceleration term at weight 1, no ridge, |Xi| < 0.01 dropped) are
trained and evaluated beside each under ``paper_defaults``.
"""

from symrom.experiments.reproduce.config import (
                                                 MAX_TERMS,
                                                 PARTS,
                                                 QUICK_SELECTION,
                                                 DatasetSpec,
                                                 ExperimentSpec,
                                                 ReproduceConfig,
                                                 paper_reference,
                                                 reproduce_config,
)
from symrom.experiments.reproduce.run import manifest, reproduce, summary_lines, sweep_line
from symrom.experiments.reproduce.sim import run_learned
from symrom.experiments.reproduce.sim2real import (
                                                 DEFAULT_METHOD,
                                                 PROXY_METHODS,
                                                 SIM2REAL,
                                                 Sim2RealTarget,
                                                 proxy_selection,
                                                 repair_summary,
                                                 sim2real_checks,
                                                 table_source,
)
from symrom.experiments.reproduce.steps import ensure_dataset, selected_config

__all__ = ["DEFAULT_METHOD", "MAX_TERMS", "PARTS", "PROXY_METHODS", "QUICK_SELECTION", "SIM2REAL", "DatasetSpec",
           "ExperimentSpec", "ReproduceConfig", "Sim2RealTarget", "ensure_dataset", "manifest", "paper_reference",
           "proxy_selection", "repair_summary", "reproduce", "reproduce_config", "run_learned", "selected_config",
           "sim2real_checks", "summary_lines", "sweep_line", "table_source"]
