"""HybridModel: the autoencoder, the library and one coefficient matrix per phase.

Latent dynamics in phase k: ddxi = Theta(xi, dxi, nu) Xi_k. The model is the
fitted state of a ``SymbolicROM`` and what a model file holds; it implements
the rollout protocol (``symrom.rollout.system.Rollable``), so ``rollout`` and
``evaluate`` treat it like any other model.

Data meet a model through names: a dataset's phases are mapped to the
model's phases by name, its robot and joint layout must be the model's, and a
phase the model was not trained on cannot be rolled out. Each mismatch raises
``ModelDataError`` with one line saying what differs and where.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any, ClassVar

import numpy as np

from symrom import compiled
from symrom.compiled import JumpViews, LatentDynamics, decode_jumps, encode_inputs, encode_states
from symrom.data.dataset import Dataset
from symrom.model.autoencoder import LinearAutoencoder
from symrom.model.expressions import Equations, latent_dynamics, latent_expressions
from symrom.model.guards import Guard
from symrom.model.library import Library
from symrom.model.provenance import Provenance
from symrom.motions import phase_sequence
from symrom.names import Q_NAMES
from symrom.rollout.system import GeneratedCode, Padded, RolloutSystem

# A phase's linearised dynamics grow by more than this factor over a typical
# stay in the phase: a "fast" unstable mode, worth a warning.
FAST_GROWTH = 10.0


class ModelDataError(ValueError):
    """Data that the model cannot be used on (phases, robot, layout); one clear line."""


@dataclass
class PhaseInfo:
    """What training saw of one phase.

    trained: whether the training data held rows of it; n_rows: how many;
    operating_point (3l,): mean [xi, dxi, nu] over those rows, where the
    stability diagnostics linearise; duration_s: median length of a contiguous
    stay in the phase, s; report: the regressor's record (terms left out and
    why, sparsity path, refinement), JSON-ready.
    """

    trained: bool = True
    n_rows: int = 0
    operating_point: np.ndarray | None = None
    duration_s: float | None = None
    report: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["operating_point"] = None if self.operating_point is None else np.asarray(self.operating_point).tolist()
        return d


@dataclass
class PhaseStability:
    """Eigenvalues (2l,) complex of a phase's dynamics linearised at its operating
    point; growth: exp(max real part x duration), the factor by which the fastest
    mode grows over a typical stay in the phase (None without a duration)."""

    phase: str
    eigenvalues: np.ndarray
    duration_s: float | None

    @property
    def max_real(self) -> float:
        return float(np.max(self.eigenvalues.real))

    @property
    def growth(self) -> float | None:
        if self.duration_s is None:
            return None
        return float(np.exp(min(self.max_real * self.duration_s, 700.0)))

    @property
    def fast_unstable(self) -> bool:
        return self.growth is not None and self.growth > FAST_GROWTH

    def warning(self) -> str | None:
        """One line if the phase has a fast unstable mode, else None."""
        if not self.fast_unstable:
            return None
        return (f"phase {self.phase!r} has a fast unstable mode: eigenvalue real part "
                f"{self.max_real:.3g} /s grows {self.growth:.3g}x over a typical {self.duration_s:.3g} s "
                f"in the phase; long rollouts may diverge")

    def to_dict(self) -> dict:
        return {"phase": self.phase, "eigenvalues": [[float(z.real), float(z.imag)] for z in self.eigenvalues],
                "max_real": self.max_real, "duration_s": self.duration_s, "growth": self.growth,
                "fast_unstable": self.fast_unstable}


@dataclass
class HybridModel:
    """autoencoder; library; phase_names (P,); Xi (P, p, l); mask (P, p, l) bool;
    latent_scale (2l,): largest |xi|, |dxi| seen in training, the yardstick for
    divergence; provenance: where it comes from (``symrom.model.provenance.Provenance``:
    the data, the training settings, the selection, the fine-tuning; an immutable value,
    replaced, never edited); phase_info: per phase name, what training saw of it; estimator: the
    configuration of the learner that fitted it (its plug-ins, ``{"encoder": {"kind":
    ...}, "regressor": {"kind": ...}, "decoded_weight", "contact_phase",
    "path_thresholds"}``), JSON-ready: kept here, read by ``symrom.learn``; guards: the
    learned contact switches (``symrom.model.guards``), None for a model fitted without
    them (files of format 3 and older)."""

    autoencoder: LinearAutoencoder
    library: Library
    phase_names: list[str]
    Xi: np.ndarray
    mask: np.ndarray
    latent_scale: np.ndarray
    provenance: Provenance = field(default_factory=Provenance)
    phase_info: dict[str, PhaseInfo] = field(default_factory=dict)
    estimator: dict[str, Any] = field(default_factory=dict)
    guards: list[Guard] | None = None

    components: ClassVar[tuple[str, ...]] = Q_NAMES

    def __post_init__(self) -> None:
        P, p, l = len(self.phase_names), self.library.n_features, self.autoencoder.latent_dim
        if self.library.latent_dim != l:
            raise ValueError(f"library latent_dim {self.library.latent_dim} != autoencoder's {l}")
        for name, arr in (("Xi", self.Xi), ("mask", self.mask)):
            if np.shape(arr) != (P, p, l):
                raise ValueError(f"{name}: shape {np.shape(arr)}, expected {(P, p, l)}")
        if np.shape(self.latent_scale) != (2 * l,):
            raise ValueError(f"latent_scale: shape {np.shape(self.latent_scale)}, expected {(2 * l,)}")
        if len(set(self.phase_names)) != P:
            raise ValueError(f"phase names repeat: {self.phase_names}")
        for g in self.guards or []:
            for name in (g.source, g.target):
                if name not in self.phase_names:
                    raise ValueError(f"guard {g.source}->{g.target}: phase {name!r} is not one of "
                                     f"{self.phase_names}")
            g.indices(l)

    @property
    def latent_dim(self) -> int:
        return self.autoencoder.latent_dim

    @property
    def yardstick(self) -> np.ndarray:
        """(2l,) what a rollout's divergence bound multiplies (``RolloutOptions.bound``): the
        largest |xi|, |dxi| seen in training, plus 1e-3 so a latent that never moved has a bound."""
        return np.asarray(self.latent_scale) + 1e-3

    def active_terms(self) -> dict[str, int]:
        """Number of nonzero coefficients per phase."""
        return {n: int(self.mask[i].sum()) for i, n in enumerate(self.phase_names)}

    def phase_sequence(self) -> tuple[int, ...]:
        """The model's phase indices along one jump of its motion (``symrom.motions``: a
        pronk's contact, flight, contact), what a free prediction follows; () when the motion
        is not in the registry or a phase of its sequence is not a trained phase of the model
        (then the guards may switch in any order)."""
        names = phase_sequence(self.provenance.data.motion)
        trained = self.trained_phases()
        if not names or any(n not in trained for n in names):
            return ()
        return tuple(self.phase_names.index(n) for n in names)

    def trained_phases(self) -> list[str]:
        """The phases whose equations were fitted to data (all, for models without phase_info)."""
        return [n for n in self.phase_names if n not in self.phase_info or self.phase_info[n].trained]

    # ------------------------------------------------------------ the dynamics
    def dynamics(self) -> LatentDynamics:
        """The latent dynamics as the compiled code reads them (``symrom.compiled``)."""
        return latent_dynamics(self.library, self.Xi, self.phase_names)

    def latent_acceleration(self, xi: np.ndarray, dxi: np.ndarray, nu: np.ndarray,
                            phase: np.ndarray) -> np.ndarray:
        """ddxi (N, l) from xi, dxi, nu (N, l) and model phase indices (N,)."""
        theta = self.library.transform(xi, dxi, nu)  # (N, p)
        return np.einsum("np,npl->nl", theta, self.Xi[np.asarray(phase)])

    def linearisation(self, phase: int, xi: np.ndarray, dxi: np.ndarray, nu: np.ndarray) -> np.ndarray:
        """(2l, 2l) Jacobian of d[xi, dxi]/dt in ``phase`` at one state xi, dxi, nu (l,)."""
        l = self.latent_dim
        J = self.library.jacobian(xi[None], dxi[None], nu[None])[0]  # (p, 2l)
        A = np.zeros((2 * l, 2 * l))
        A[:l, l:] = np.eye(l)
        A[l:] = self.Xi[phase].T @ J
        return A

    def stability(self) -> list[PhaseStability]:
        """Per trained phase with an operating point, the eigenvalues of its linearisation."""
        l = self.latent_dim
        out = []
        for k, name in enumerate(self.phase_names):
            info = self.phase_info.get(name)
            if info is None or not info.trained or info.operating_point is None:
                continue
            op = np.asarray(info.operating_point, dtype=float)
            A = self.linearisation(k, op[:l], op[l:2 * l], op[2 * l:])
            out.append(PhaseStability(name, np.linalg.eigvals(A), info.duration_s))
        return out

    # ------------------------------------------------------------ data guards
    def phase_index(self, ds: Dataset, rows: np.ndarray | None = None) -> np.ndarray:
        """Model phase index (N,) of each row of ``ds`` (or of ``rows``), matched by name.

        Raises ``ModelDataError`` naming the first row in a phase the model has no
        equations for, or was not trained on.
        """
        lookup = np.full(len(ds.phase_names), -1)
        for i, name in enumerate(ds.phase_names):
            if name in self.phase_names:
                lookup[i] = self.phase_names.index(name)
        phase = np.asarray(ds.phase if rows is None else ds.phase[rows], dtype=int)
        idx = lookup[phase]
        untrained = [self.phase_names.index(n) for n in self.phase_names if n not in self.trained_phases()]
        bad = (idx < 0) | np.isin(idx, untrained)
        if bad.any():
            r = int(np.flatnonzero(bad)[0])
            row = r if rows is None else int(np.flatnonzero(rows)[r])
            name = ds.phase_names[phase[r]]
            why = ("the model has no equations for it" if name not in self.phase_names
                   else "the model's training data held no row of it")
            raise ModelDataError(f"phase {name!r} (jump {int(ds.jump[row])}, row {row}): {why} "
                                 f"(model phases: {', '.join(self.trained_phases())})")
        return idx

    def check_data(self, ds: Dataset) -> None:
        """Raise ``ModelDataError`` if ``ds`` is of another robot or joint layout than the model."""
        robot = self.provenance.data.robot
        if robot is not None and ds.robot != robot:
            raise ModelDataError(f"robot: the model was trained on {robot!r}, the data are of {ds.robot!r}")
        layout = self.provenance.data.q_names
        if layout is not None and list(layout) != list(Q_NAMES):
            raise ModelDataError("joint layout: the model's configuration components "
                                 f"{list(layout)} differ from this symrom's {list(Q_NAMES)}")

    # ------------------------------------------------------------ rollouts
    def rollout_system(self, ds: Dataset, jumps: np.ndarray) -> RolloutSystem:
        """The latent system on ``jumps`` of ``ds`` (protocol ``Rollable``): encoded true
        state, held latent inputs nu and phase, decoded predictions of all 18 components."""
        self.check_data(ds)
        phase = self.phase_index(ds)
        # All jumps encoded in compiled passes straight into the integrators' padded arrays; the
        # true states only where an integrator reads them (or in full when the lists are read).
        ae, bounds = self.autoencoder, ds.jump_bounds()[jumps]
        lens = bounds[:, 1] - bounds[:, 0]
        nu, ph = encode_inputs(ae, ds.u, phase, bounds)
        full = functools.cache(lambda: encode_states(ae, ds.q, ds.dq, bounds))
        x, v = JumpViews(lambda: full()[0], lens), JumpViews(lambda: full()[1], lens)
        scale = np.broadcast_to(self.yardstick, (len(jumps), 2 * self.latent_dim))
        padded = Padded(lambda rows: encode_states(ae, ds.q, ds.dq, bounds, rows), {"nu": nu, "phase": ph}, lens)
        return self.latent_system(x, v, JumpViews(lambda: nu, lens), JumpViews(lambda: ph, lens), scale, padded)

    def latent_system(self, x: Sequence[np.ndarray], v: Sequence[np.ndarray], nu: Sequence[np.ndarray],
                      ph: Sequence[np.ndarray], scale: np.ndarray, padded: Padded | None = None) -> RolloutSystem:
        """The latent ``RolloutSystem`` of given paths: per path, start/reset states x, v
        (n, l), held inputs nu (n, l) and model phase indices (n,); scale (J, 2l); padded:
        the same stacked, if at hand (``RolloutSystem.padded``)."""
        lib, Xi, ae = self.library, self.Xi, self.autoencoder
        dyn = self.dynamics()

        def c_params(drive: dict[str, np.ndarray]) -> np.ndarray:
            """(n, 1 + l): the C right-hand side's data per sample, [phase index, nu]."""
            return np.column_stack([drive["phase"], drive["nu"]]).astype(float)

        def acceleration(drive: dict[str, np.ndarray], xs: np.ndarray, vs: np.ndarray) -> np.ndarray:
            return np.einsum("jp,jpl->jl", lib.transform(xs, vs, drive["nu"]), Xi[drive["phase"]])

        def generated() -> GeneratedCode:
            code = compiled.generated(dyn)
            return GeneratedCode(integrator=code.integrator, rhs=code.rhs,
                                 rhs_args=lambda drive, k: (int(drive["phase"][k]), drive["nu"][k]),
                                 c_rhs=code.c_rhs, c_params=c_params)

        return RolloutSystem(x, v, {"nu": nu, "phase": ph}, scale, acceleration,
                             lambda i, X: ae.decode(X), compiled.table_integrator(lib.terms, Xi), generated,
                             lambda: compiled.has_build(dyn), padded, lambda X, lens: decode_jumps(ae, X, lens),
                             dyn.key)

    # ------------------------------------------------------------ free prediction
    def inputs_from_torques(self, q: np.ndarray, tau: np.ndarray, contact: np.ndarray,
                            foot_pos: np.ndarray | None = None) -> np.ndarray:
        """u (N, 18) from q (N, 18), torques (N, 12) N m reaching the joints (a robot's motors' less
        the actuator effects its description states: ``symrom.data.preprocess.joint_torques``),
        contact flags (N, 4) and optional feet (N, 4, 3) m world, for the model's robot:
        ``symrom.data.preprocess.input_from_torques``."""
        from symrom.data.preprocess import input_from_torques

        robot = self.provenance.data.robot
        if robot is None:
            raise ModelDataError("the model records no robot (provenance.data.robot), whose legs map torques to u")
        return input_from_torques(robot, q, tau, contact, foot_pos)

    def predict_path(self, q0: np.ndarray, dq0: np.ndarray, inputs, dt: float, phases=None,
                     n: int | None = None, phase0: str | None = None, options=None, dwell0: float = 0.0,
                     stage0: int | None = None):
        """Roll out from a chosen state with one's own inputs; ``symrom.model.path.predict_path``
        (its docstring gives the arguments and shapes)."""
        from symrom.model.path import predict_path

        return predict_path(self, q0, dq0, inputs, dt, phases=phases, n=n, phase0=phase0, options=options,
                            dwell0=dwell0, stage0=stage0)

    # ------------------------------------------------------------ equations
    def equations(self, digits: int = 3) -> Equations:
        """The model's equations (``symrom.model.expressions.Equations``): per phase the l
        right-hand sides of ddxi_j as sympy expressions, coefficients rounded to ``digits``
        significant digits; with the contact switches and what each latent reads. ``str()``
        gives the text of ``equations.txt``, ``latex()`` the LaTeX."""
        return Equations(dict(zip(self.phase_names, latent_expressions(self.library, self.Xi, digits))),
                         self.guards or (), self.latent_loadings(), digits)

    def latent_loadings(self, share: float = 0.1, most: int = 4) -> list[tuple[list[tuple[str, float]], int]]:
        """What each latent reads: per xi_i, the configuration components (``Q_NAMES``) of its
        encoder row W_e[i] whose |weight| is at least ``share`` of the row's largest, largest
        first, at most ``most`` of them (name, weight per unit of the component: 1/rad or
        1/m), and how many more pass ``share``."""
        out = []
        for row in self.autoencoder.W_e:
            big = np.abs(row)
            keep = [int(k) for k in np.argsort(-big, kind="stable") if big[k] >= share * big.max() > 0]
            out.append(([(Q_NAMES[k], float(row[k])) for k in keep[:most]], max(len(keep) - most, 0)))
        return out

    def stability_text(self, latex: bool = False) -> str:
        """Each phase's eigenvalues linearised at its training mean, one line per phase after a
        heading ('' for a model without operating points); LaTeX: ``\\lambda_{...} \\in \\{...\\}``."""
        stab = self.stability()
        if not stab:
            return ""
        lines = ["% linearised at each phase's training mean: eigenvalues (1/s)" if latex
                 else "linearised at each phase's training mean: eigenvalues (1/s)"]
        for st in stab:
            zs = sorted(st.eigenvalues, key=lambda z: (-z.real, z.imag))
            if latex:
                eig = ",\\ ".join(f"{z.real:.3g} {'+' if z.imag >= 0 else '-'} {abs(z.imag):.3g}i"
                                   if abs(z.imag) > 1e-12 else f"{z.real:.3g}" for z in zs)
                growth = "" if st.growth is None else (rf" \quad \text{{(fastest mode $\times${st.growth:.3g} "
                                                       rf"over {st.duration_s:.3g} s)}}")
                name = st.phase.replace("_", r"\_")
                lines.append(rf"\lambda_{{\mathrm{{{name}}}}} \in \{{{eig}\}}{growth}")
                continue
            eig = ", ".join(f"{z.real:.3g}{z.imag:+.3g}j" if abs(z.imag) > 1e-12 else f"{z.real:.3g}" for z in zs)
            growth = "" if st.growth is None else f"  (fastest mode x{st.growth:.3g} over {st.duration_s:.3g} s)"
            lines.append(f"[{st.phase}] {eig}{growth}")
        return "\n".join(lines)

    # ------------------------------------------------------------ in words
    def summary(self) -> str:
        """'l=2, p=1, 20 library terms; active terms: contact 5, flight 3'."""
        terms = ", ".join(f"{k} {v}" for k, v in self.active_terms().items())
        return (f"l={self.latent_dim}, p={self.library.poly_order}, {self.library.n_features} library terms; "
                f"active terms: {terms}")

    def training_rows(self) -> str:
        """'contact 1200 rows, flight 400 rows': the training rows per phase ('' if not recorded)."""
        return ", ".join(f"{n} {p.n_rows} rows" if p.n_rows else f"{n} none" for n, p in self.phase_info.items())

    def warnings(self) -> list[str]:
        """What a reader should know before using the model, one line each: the phases it could
        not fit, an encoder fitted on all rows (the data held no contact row), and each phase
        with a fast unstable mode."""
        out = []
        untrained = self.provenance.training.untrained_phases
        if untrained:
            out.append(f"can fit: {', '.join(self.trained_phases())}; cannot fit: {', '.join(untrained)} (no "
                       "training rows: its equations stay zero and rollouts through it are refused)")
        rows = self.provenance.training.encoder_rows or ""
        if rows.startswith("all"):
            out.append(f"the encoder (step a) is fitted on {rows}")
        out += [st.warning() for st in self.stability() if st.warning()]
        return out
