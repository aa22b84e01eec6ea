"""Pictures of a logged jump: replay its configurations in an engine and save PNG frames.

The robot is posed at each chosen sample's ``q`` (18,) (no physics). PyBullet
draws it with its software renderer (TinyRenderer, ``getCameraImage``) in a
DIRECT-mode world; MuJoCo with ``mujoco.Renderer``, which needs an OpenGL
context (``MUJOCO_GL``, set to ``egl`` here unless the environment says otherwise:
headless machines with a GPU driver or Mesa's EGL). A side camera follows the
base. Frames are written as PNG with matplotlib.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

# MuJoCo picks its OpenGL platform when it is imported: headless EGL unless told otherwise
os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np

from symrom.data.dataset import Dataset
from symrom.names import BASE_POS, N_Q
from symrom.sim.engines.registry import make_world

if TYPE_CHECKING:
    from symrom.sim.engines.bullet import BulletWorld


@dataclass(frozen=True)
class CameraConfig:
    """Side view: image size (pixels), distance (m), yaw/pitch (deg), field of view (deg)."""

    width: int = 480
    height: int = 360
    distance: float = 1.1
    yaw: float = 0.0
    pitch: float = -15.0
    fov: float = 60.0


def frame_rows(n_rows: int, n_frames: int) -> np.ndarray:
    """Indices of ``n_frames`` samples spread evenly over ``n_rows`` (first and last included)."""
    n_frames = max(1, min(n_frames, n_rows))
    return np.unique(np.linspace(0, n_rows - 1, n_frames).round().astype(int))


def render_q(world: BulletWorld, q: np.ndarray, camera: CameraConfig = CameraConfig(),
             target: np.ndarray | None = None) -> np.ndarray:
    """RGB image (height, width, 3) uint8 of the robot posed at ``q`` (18,) in a PyBullet world,
    by PyBullet's software renderer."""
    from symrom.sim.engines.bullet import p

    world.reset(np.asarray(q, dtype=float))
    c = camera
    look = np.asarray(q[BASE_POS] if target is None else target, dtype=float).copy()
    view = p.computeViewMatrixFromYawPitchRoll(look.tolist(), c.distance, c.yaw, c.pitch, 0.0, 2,
                                               physicsClientId=world.client)
    proj = p.computeProjectionMatrixFOV(c.fov, c.width / c.height, 0.05, 10.0,
                                        physicsClientId=world.client)
    _, _, rgba, _, _ = p.getCameraImage(c.width, c.height, view, proj,
                                        renderer=p.ER_TINY_RENDERER, physicsClientId=world.client)
    return np.asarray(rgba, dtype=np.uint8).reshape(c.height, c.width, 4)[:, :, :3]


class _MujocoPainter:
    """Draws a ``MujocoWorld`` posed at q with ``mujoco.Renderer`` (one per jump)."""

    def __init__(self, world, camera: CameraConfig):
        import mujoco

        self.mj, self.world, self.camera = mujoco, world, camera
        try:
            self.renderer = mujoco.Renderer(world.model, camera.height, camera.width)
        except Exception as e:  # no OpenGL context on this machine
            raise RuntimeError(f"MuJoCo cannot render here (MUJOCO_GL={os.environ['MUJOCO_GL']}: {e}); "
                               f"use engine='pybullet'") from None

    def __call__(self, q: np.ndarray, target: np.ndarray) -> np.ndarray:
        self.world.reset(np.asarray(q, dtype=float))
        cam, c = self.mj.MjvCamera(), self.camera
        cam.lookat[:], cam.distance = target, c.distance
        cam.azimuth, cam.elevation = 90.0 + c.yaw, c.pitch  # looking along +y: the side view
        self.renderer.update_scene(self.world.data, camera=cam)
        return self.renderer.render().copy()


def render_jump(ds: Dataset, jump: int, out_dir: str | Path, n_frames: int = 8,
                camera: CameraConfig = CameraConfig(), engine: str = "pybullet") -> list[Path]:
    """Write ``n_frames`` PNGs of jump ``jump`` of ``ds`` into ``out_dir``; return their paths.

    Files are named ``jump_0003_t0.842.png`` (t in s since the jump's start). The
    camera looks at the jump's mean base position (height of the first sample),
    so the frames show the robot travelling. engine: ``pybullet`` or ``mujoco``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if not 0 <= jump < ds.n_jumps:
        raise ValueError(f"jump {jump} is not in the file (it has jumps 0..{ds.n_jumps - 1})")
    a, b = ds.jump_bounds()[jump]
    q, t = ds.q[a:b], ds.t[a:b]
    if q.shape[1] != N_Q:
        raise ValueError(f"q has {q.shape[1]} columns, expected {N_Q}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    target = q[:, BASE_POS].mean(axis=0)
    target[2] = q[0, BASE_POS][2]
    paths = []
    world = make_world(engine, ds.robot)
    try:
        paint = ((lambda qr, tg: render_q(world, qr, camera, tg)) if engine == "pybullet"
                 else _MujocoPainter(world, camera))
        for r in frame_rows(q.shape[0], n_frames):
            img = paint(q[r], target)
            path = out_dir / f"jump_{jump:04d}_t{t[r]:.3f}.png"
            plt.imsave(path, img)
            paths.append(path)
    finally:
        world.close()
    return paths
