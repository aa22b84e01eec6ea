"""The SINDy candidate library Theta(xi, dxi, nu), composed of term blocks.

A block is one family of candidate terms. It states, in one place, the names
of its terms, their numeric columns, the derivatives of those columns with
respect to the latent state, and their sympy form:

- ``Polynomial(order)``: every monomial of the 2l latent positions and
  velocities s = [xi, dxi] up to total degree ``order``, the constant first;
- ``Trigonometric()``: sin of each of the 2l state variables, then cos of each;
- ``Inputs()``: the l latent inputs nu, linearly;
- ``Custom(expressions)``: any expressions of ``xi1..xil, dxi1..dxil,
  nu1..nul`` written with sympy's syntax and a small set of functions.

Blocks concatenate with ``+`` (``Polynomial(1) + Trigonometric() + Inputs()``,
the paper's library) into a ``LibrarySpec``; ``spec.bind(l)`` gives the
``Library`` of a latent space of dimension l. The paper's count (Table 1) is
sum_k C(2l+k-1, k) + 2(2l) + l candidates: 15 for l = 2, p = 1 and 29 for
l = 4, p = 1.
"""

from __future__ import annotations

import re
from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from itertools import combinations_with_replacement
from typing import ClassVar

import numpy as np
import sympy

from symrom.compiled import TermLibrary

# Preference among near-collinear candidates (lower is simpler and kept first):
# the constant, then single state variables, inputs, higher monomials, trig, custom.
RANK_CONSTANT, RANK_LINEAR, RANK_INPUT, RANK_MONOMIAL, RANK_TRIG, RANK_CUSTOM = range(6)


def state_names(l: int) -> list[str]:
    """Names of the 2l state variables: xi1..xil, dxi1..dxil."""
    return [f"xi{i + 1}" for i in range(l)] + [f"dxi{i + 1}" for i in range(l)]


def input_names(l: int) -> list[str]:
    return [f"nu{i + 1}" for i in range(l)]


def symbols(l: int) -> tuple[list[sympy.Symbol], list[sympy.Symbol]]:
    """sympy symbols of the state [xi1.., dxi1..] (2l) and of the inputs nu1.. (l)."""
    return [sympy.Symbol(n) for n in state_names(l)], [sympy.Symbol(n) for n in input_names(l)]


class TermBlock(ABC):
    """One family of candidate terms of a latent space of dimension l.

    Arrays: s (N, 2l) = [xi, dxi], nu (N, l). ``columns`` gives (N, k) values,
    ``jacobian`` (N, k, 2l) their derivatives with respect to s.
    """

    kind: ClassVar[str] = ""

    @abstractmethod
    def names(self, l: int) -> list[str]:
        """The k term names."""

    @abstractmethod
    def sympy(self, l: int) -> list[sympy.Expr]:
        """The k terms as sympy expressions of ``symbols(l)``."""

    @abstractmethod
    def ranks(self, l: int) -> list[int]:
        """The k terms' preference among near-collinear candidates (``RANK_*``)."""

    @abstractmethod
    def columns(self, s: np.ndarray, nu: np.ndarray) -> np.ndarray:
        """(N, k) values."""

    @abstractmethod
    def jacobian(self, s: np.ndarray, nu: np.ndarray) -> np.ndarray:
        """(N, k, 2l) derivatives of the columns with respect to s."""

    @abstractmethod
    def to_dict(self) -> dict:
        """JSON-ready form, read back by ``block_from_dict``."""

    def __add__(self, other: TermBlock | LibrarySpec) -> LibrarySpec:
        return LibrarySpec((self,)) + other


@dataclass(frozen=True)
class Polynomial(TermBlock):
    """Monomials of the state s = [xi, dxi] up to total degree ``order`` (constant included)."""

    order: int = 1
    kind: ClassVar[str] = "polynomial"

    def __post_init__(self) -> None:
        if not (isinstance(self.order, int) and self.order >= 0):
            raise ValueError(f"polynomial order must be an integer >= 0, got {self.order!r}")

    def monomials(self, l: int) -> list[tuple[int, ...]]:
        """Index tuples into s of every monomial, by degree (() is the constant)."""
        return [c for d in range(self.order + 1) for c in combinations_with_replacement(range(2 * l), d)]

    def names(self, l: int) -> list[str]:
        s = state_names(l)
        out = []
        for m in self.monomials(l):
            parts = [s[i] if m.count(i) == 1 else f"{s[i]}^{m.count(i)}" for i in sorted(set(m))]
            out.append("*".join(parts) if parts else "1")
        return out

    def sympy(self, l: int) -> list[sympy.Expr]:
        s, _ = symbols(l)
        return [sympy.Mul(*[s[i] for i in m]) if m else sympy.Integer(1) for m in self.monomials(l)]

    def ranks(self, l: int) -> list[int]:
        return [RANK_CONSTANT if not m else RANK_LINEAR if len(m) == 1 else RANK_MONOMIAL
                for m in self.monomials(l)]

    # Monomials come by degree: the constant, then s itself (degree 1, in order),
    # then the products; the first two are written directly since rollouts call these often.
    def columns(self, s: np.ndarray, nu: np.ndarray) -> np.ndarray:
        d = s.shape[1]
        cols = [np.ones((s.shape[0], 1)), s] if self.order >= 1 else [np.ones((s.shape[0], 1))]
        cols += [np.prod(s[:, list(m)], axis=1)[:, None] for m in self.monomials(d // 2)[1 + d:]]
        return np.concatenate(cols, axis=1)

    def jacobian(self, s: np.ndarray, nu: np.ndarray) -> np.ndarray:
        d = s.shape[1]
        mons = self.monomials(d // 2)
        J = np.zeros((s.shape[0], len(mons), d))
        if self.order >= 1:
            J[:, 1:1 + d, :] = np.eye(d)
        for k, m in enumerate(mons[1 + d:], start=1 + d):
            for i in set(m):
                rest = list(m)
                rest.remove(i)  # d/ds_i s_i^c * r = c s_i^(c-1) r
                J[:, k, i] = m.count(i) * np.prod(s[:, rest], axis=1)
        return J

    def to_dict(self) -> dict:
        return {"kind": self.kind, "order": self.order}


@dataclass(frozen=True)
class Trigonometric(TermBlock):
    """sin of each state variable [xi, dxi], then cos of each."""

    kind: ClassVar[str] = "trigonometric"

    def names(self, l: int) -> list[str]:
        s = state_names(l)
        return [f"sin({v})" for v in s] + [f"cos({v})" for v in s]

    def sympy(self, l: int) -> list[sympy.Expr]:
        s, _ = symbols(l)
        return [sympy.sin(v) for v in s] + [sympy.cos(v) for v in s]

    def ranks(self, l: int) -> list[int]:
        return [RANK_TRIG] * (4 * l)

    def columns(self, s: np.ndarray, nu: np.ndarray) -> np.ndarray:
        return np.concatenate([np.sin(s), np.cos(s)], axis=1)

    def jacobian(self, s: np.ndarray, nu: np.ndarray) -> np.ndarray:
        n, d = s.shape
        J = np.zeros((n, 2 * d, d))
        idx = np.arange(d)
        J[:, idx, idx] = np.cos(s)
        J[:, d + idx, idx] = -np.sin(s)
        return J

    def to_dict(self) -> dict:
        return {"kind": self.kind}


@dataclass(frozen=True)
class Inputs(TermBlock):
    """The latent inputs nu1..nul, linearly."""

    kind: ClassVar[str] = "inputs"

    def names(self, l: int) -> list[str]:
        return input_names(l)

    def sympy(self, l: int) -> list[sympy.Expr]:
        return list(symbols(l)[1])

    def ranks(self, l: int) -> list[int]:
        return [RANK_INPUT] * l

    def columns(self, s: np.ndarray, nu: np.ndarray) -> np.ndarray:
        return np.asarray(nu, dtype=float).reshape(s.shape[0], -1)

    def jacobian(self, s: np.ndarray, nu: np.ndarray) -> np.ndarray:
        return np.zeros((s.shape[0], s.shape[1] // 2, s.shape[1]))

    def to_dict(self) -> dict:
        return {"kind": self.kind}


# What a custom expression may contain: numbers, the latent symbols, + - * / ** ( ) ,
# and these functions. Checked before sympy parses it, since sympy's parser evaluates
# Python and a model file may come from elsewhere.
CUSTOM_FUNCTIONS = ("sin", "cos", "tan", "exp", "log", "sqrt", "tanh", "Abs", "sign", "atan")
_TOKEN = re.compile(r"\s*(?:(\d+\.?\d*(?:[eE][-+]?\d+)?|\.\d+(?:[eE][-+]?\d+)?)|([A-Za-z_]\w*)|(\*\*|[-+*/(),]))")


_LATENT = re.compile(r"(?:xi|dxi|nu)[1-9]\d*")


def parse_expression(text: str, l: int | None) -> sympy.Expr | None:
    """A sympy expression from ``text`` over xi1..xil, dxi1..dxil, nu1..nul and
    ``CUSTOM_FUNCTIONS``; ValueError naming the first token that is not allowed.
    With ``l`` None, only check the text (any latent index) and return None."""
    allowed = set(CUSTOM_FUNCTIONS) | (set() if l is None else set(state_names(l)) | set(input_names(l)))
    pos = 0
    text = str(text)
    while pos < len(text.rstrip()):
        m = _TOKEN.match(text, pos)
        if not m or m.end() == pos:
            raise ValueError(f"custom term {text!r}: cannot read {text[pos:].strip()[:12]!r}")
        name = m.group(2)
        if name and name not in allowed and not (l is None and _LATENT.fullmatch(name)):
            raise ValueError(f"custom term {text!r}: unknown name {name!r} (allowed: xi<i>, dxi<i>, "
                             f"nu<i> for i <= the latent dimension, and {', '.join(CUSTOM_FUNCTIONS)})")
        pos = m.end()
    if l is None:
        return None
    s, nu = symbols(l)
    local = {str(v): v for v in [*s, *nu]} | {f: getattr(sympy, f) for f in CUSTOM_FUNCTIONS}
    try:
        return sympy.sympify(text, locals=local)
    except (sympy.SympifyError, SyntaxError, TypeError) as e:
        raise ValueError(f"custom term {text!r}: not a valid expression ({e})") from None


@dataclass(frozen=True)
class Custom(TermBlock):
    """User terms: ``expressions`` over xi1.., dxi1.., nu1.. (e.g. ``"xi1*nu2"``,
    ``"exp(-xi2)"``), with optional display ``labels`` (default: the expression)."""

    expressions: tuple[str, ...] = ()
    labels: tuple[str, ...] | None = None
    kind: ClassVar[str] = "custom"
    _compiled: dict = field(default_factory=dict, compare=False, hash=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "expressions", tuple(str(e) for e in self.expressions))
        if not self.expressions:
            raise ValueError("a custom block needs at least one expression")
        for e in self.expressions:
            parse_expression(e, None)
        if self.labels is not None:
            object.__setattr__(self, "labels", tuple(str(x) for x in self.labels))
            if len(self.labels) != len(self.expressions):
                raise ValueError(f"custom block: {len(self.labels)} labels for "
                                 f"{len(self.expressions)} expressions")

    def sympy(self, l: int) -> list[sympy.Expr]:
        return [parse_expression(e, l) for e in self.expressions]

    def names(self, l: int) -> list[str]:
        return list(self.labels) if self.labels else [sympy.sstr(e) for e in self.sympy(l)]

    def ranks(self, l: int) -> list[int]:
        return [RANK_CUSTOM] * len(self.expressions)

    def _functions(self, l: int):
        if l not in self._compiled:
            s, nu = symbols(l)
            exprs = self.sympy(l)
            args = [*s, *nu]
            value = [sympy.lambdify(args, e, "numpy") for e in exprs]
            grad = [[sympy.lambdify(args, sympy.diff(e, v), "numpy") for v in s] for e in exprs]
            self._compiled[l] = (value, grad)
        return self._compiled[l]

    def columns(self, s: np.ndarray, nu: np.ndarray) -> np.ndarray:
        value, _ = self._functions(s.shape[1] // 2)
        args = [*s.T, *np.asarray(nu, dtype=float).reshape(s.shape[0], -1).T]
        return np.stack([np.broadcast_to(f(*args), (s.shape[0],)) for f in value], axis=1).astype(float)

    def jacobian(self, s: np.ndarray, nu: np.ndarray) -> np.ndarray:
        _, grad = self._functions(s.shape[1] // 2)
        args = [*s.T, *np.asarray(nu, dtype=float).reshape(s.shape[0], -1).T]
        return np.stack([np.stack([np.broadcast_to(g(*args), (s.shape[0],)) for g in row], axis=1)
                         for row in grad], axis=1).astype(float)

    def to_dict(self) -> dict:
        d = {"kind": self.kind, "expressions": list(self.expressions)}
        if self.labels is not None:
            d["labels"] = list(self.labels)
        return d


BLOCKS: dict[str, type[TermBlock]] = {b.kind: b for b in (Polynomial, Trigonometric, Inputs, Custom)}


def block_from_dict(d: dict) -> TermBlock:
    """A block from its ``to_dict`` form; ValueError naming a bad kind or field."""
    if not isinstance(d, dict) or d.get("kind") not in BLOCKS:
        raise ValueError(f"library block {d!r}: unknown kind (known: {', '.join(BLOCKS)})")
    kind = d["kind"]
    if kind == "polynomial":
        return Polynomial(int(d.get("order", 1)))
    if kind == "custom":
        labels = d.get("labels")
        return Custom(tuple(d.get("expressions", ())), None if labels is None else tuple(labels))
    return BLOCKS[kind]()


@dataclass(frozen=True)
class LibrarySpec:
    """An ordered concatenation of term blocks, not yet bound to a latent dimension."""

    blocks: tuple[TermBlock, ...]

    def __add__(self, other: TermBlock | LibrarySpec) -> LibrarySpec:
        more = other.blocks if isinstance(other, LibrarySpec) else (other,)
        if not all(isinstance(b, TermBlock) for b in more):
            return NotImplemented
        return LibrarySpec(self.blocks + tuple(more))

    def bind(self, latent_dim: int) -> Library:
        return Library(latent_dim, self.blocks)

    @staticmethod
    def standard(poly_order: int = 1, trig: bool = True, inputs: bool = True) -> LibrarySpec:
        """The paper's library: Polynomial(poly_order) [+ Trigonometric()] [+ Inputs()]."""
        blocks: list[TermBlock] = [Polynomial(poly_order)]
        if trig:
            blocks.append(Trigonometric())
        if inputs:
            blocks.append(Inputs())
        return LibrarySpec(tuple(blocks))

    def to_list(self) -> list[dict]:
        return [b.to_dict() for b in self.blocks]

    @classmethod
    def from_list(cls, blocks: Sequence[dict]) -> LibrarySpec:
        return cls(tuple(block_from_dict(b) for b in blocks))


@dataclass(frozen=True)
class Library:
    """The candidate library of a latent space of dimension ``latent_dim``: its blocks'
    terms side by side, p = ``n_features`` columns in all."""

    latent_dim: int
    blocks: tuple[TermBlock, ...]

    def __post_init__(self) -> None:
        if not (isinstance(self.latent_dim, (int, np.integer)) and self.latent_dim >= 1):
            raise ValueError(f"latent_dim must be >= 1, got {self.latent_dim}")
        object.__setattr__(self, "blocks", tuple(self.blocks))
        if not self.blocks:
            raise ValueError("a library needs at least one block")
        names = self.feature_names
        if len(set(names)) != len(names):
            dup = next(n for n in names if names.count(n) > 1)
            raise ValueError(f"library: the term {dup!r} appears twice")

    @classmethod
    def standard(cls, latent_dim: int, poly_order: int = 1, trig: bool = True,
                 inputs: bool = True) -> Library:
        """The paper's library (Table 1) for latent dimension ``latent_dim``."""
        return LibrarySpec.standard(poly_order, trig, inputs).bind(latent_dim)

    @property
    def spec(self) -> LibrarySpec:
        return LibrarySpec(self.blocks)

    @cached_property
    def _sizes(self) -> list[int]:
        return [len(b.names(self.latent_dim)) for b in self.blocks]

    @property
    def n_features(self) -> int:
        return int(sum(self._sizes))

    @cached_property
    def feature_names(self) -> list[str]:
        return [n for b in self.blocks for n in b.names(self.latent_dim)]

    def terms_reading(self, positions: np.ndarray) -> np.ndarray:
        """(p,) bool: the terms whose expression holds the latent position xi_k of any k
        where ``positions`` (l,) bool is set (their velocities dxi_k do not count)."""
        s, _ = symbols(self.latent_dim)
        read = {s[k] for k in np.flatnonzero(np.asarray(positions, dtype=bool))}
        return np.array([bool(read & e.free_symbols) for e in self.sympy_features()], dtype=bool)

    @cached_property
    def feature_ranks(self) -> np.ndarray:
        """(p,) preference of each term among near-collinear ones (lower = simpler)."""
        return np.array([r for b in self.blocks for r in b.ranks(self.latent_dim)], dtype=int)

    @property
    def poly_order(self) -> int:
        """Highest degree of the polynomial blocks (0 if none)."""
        return max((b.order for b in self.blocks if isinstance(b, Polynomial)), default=0)

    def _state(self, xi: np.ndarray, dxi: np.ndarray) -> np.ndarray:
        xi, dxi = np.asarray(xi, dtype=float), np.asarray(dxi, dtype=float)
        return np.concatenate([xi.reshape(-1, self.latent_dim), dxi.reshape(-1, self.latent_dim)], axis=1)

    def transform(self, xi: np.ndarray, dxi: np.ndarray, nu: np.ndarray) -> np.ndarray:
        """Theta: xi, dxi, nu each (N, l) -> (N, p)."""
        s = self._state(xi, dxi)
        nu = np.asarray(nu, dtype=float).reshape(s.shape[0], -1)
        return np.concatenate([b.columns(s, nu) for b in self.blocks], axis=1)

    def jacobian(self, xi: np.ndarray, dxi: np.ndarray, nu: np.ndarray) -> np.ndarray:
        """d Theta / d [xi, dxi]: (N, p, 2l)."""
        s = self._state(xi, dxi)
        nu = np.asarray(nu, dtype=float).reshape(s.shape[0], -1)
        return np.concatenate([b.jacobian(s, nu) for b in self.blocks], axis=1)

    def sympy_features(self) -> list[sympy.Expr]:
        """The terms as sympy expressions of xi1.., dxi1.., nu1.. (index from 1)."""
        return [e for b in self.blocks for e in b.sympy(self.latent_dim)]

    @cached_property
    def terms(self) -> TermLibrary:
        """The terms as the compiled code reads them (``symrom.compiled``): the sympy features
        over ``symbols(l)``, and the library's record as its identity."""
        s, nu = symbols(self.latent_dim)
        return TermLibrary(tuple(self.sympy_features()), tuple(s), tuple(nu), repr(self.to_dict()))

    def to_dict(self) -> dict:
        return {"latent_dim": int(self.latent_dim), "blocks": self.spec.to_list(),
                "feature_names": self.feature_names}

    @classmethod
    def from_dict(cls, d: dict) -> Library:
        """From ``to_dict`` (or the format-1 spec ``poly_order``/``trig``/``inputs``);
        ValueError if the stored feature names do not match the spec."""
        if "blocks" in d:
            lib = cls(int(d["latent_dim"]), LibrarySpec.from_list(d["blocks"]).blocks)
        else:
            lib = cls.standard(int(d["latent_dim"]), int(d["poly_order"]), bool(d["trig"]), bool(d["inputs"]))
        if "feature_names" in d and list(d["feature_names"]) != lib.feature_names:
            raise ValueError("library feature_names do not match its blocks")
        return lib
