"""The linear autoencoder: one constant Jacobian for q, dq, ddq and the inputs.

xi = W_e q + B_e, dxi = W_e dq, ddxi = W_e ddq, nu = pinv(W_e^T) u, and
q = W_d xi + B_d. The input map keeps power: u^T dq = nu^T dxi whenever dq lies
in the row space of W_e (the motions the latent space can represent).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from symrom.names import N_Q


@dataclass
class LinearAutoencoder:
    """W_e (l, 18), B_e (l,), W_d (18, l), B_d (18,); rows of data are samples."""

    W_e: np.ndarray
    B_e: np.ndarray
    W_d: np.ndarray
    B_d: np.ndarray

    def __post_init__(self) -> None:
        l = self.W_e.shape[0]
        for name, arr, shape in (("W_e", self.W_e, (l, N_Q)), ("B_e", self.B_e, (l,)),
                                 ("W_d", self.W_d, (N_Q, l)), ("B_d", self.B_d, (N_Q,))):
            if np.shape(arr) != shape:
                raise ValueError(f"{name}: shape {np.shape(arr)}, expected {shape}")
        self._input_map = np.linalg.pinv(self.W_e)  # (18, l): nu rows = u rows @ pinv(W_e)

    @property
    def latent_dim(self) -> int:
        return int(self.W_e.shape[0])

    @property
    def input_map(self) -> np.ndarray:
        """(18, l) pinv(W_e): nu rows = u rows @ input_map."""
        return self._input_map

    def encode(self, q: np.ndarray) -> np.ndarray:
        """q (N, 18) -> xi (N, l)."""
        return q @ self.W_e.T + self.B_e

    def encode_derivative(self, dq: np.ndarray) -> np.ndarray:
        """dq or ddq (N, 18) -> dxi or ddxi (N, l): the constant Jacobian W_e."""
        return dq @ self.W_e.T

    def encode_input(self, u: np.ndarray) -> np.ndarray:
        """u (N, 18) -> nu (N, l) = pinv(W_e^T) u, row-wise."""
        return u @ self._input_map

    def decode(self, xi: np.ndarray) -> np.ndarray:
        """xi (N, l) -> q (N, 18)."""
        return xi @ self.W_d.T + self.B_d

    def decode_derivative(self, dxi: np.ndarray) -> np.ndarray:
        """dxi or ddxi (N, l) -> (N, 18)."""
        return dxi @ self.W_d.T

    def reconstruct(self, q: np.ndarray) -> np.ndarray:
        return self.decode(self.encode(q))
