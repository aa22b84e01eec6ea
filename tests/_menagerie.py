"""The mesh-free copies of MuJoCo Menagerie's quadrupeds (tests/robots/menagerie, made by its
strip_meshes.py from the published files) and what `robot init` must find in each: shared by
the robot tests."""

from __future__ import annotations

from pathlib import Path

from symrom.robots.init import RobotInit, init_robot

FOLDER = Path(__file__).parent / "robots" / "menagerie"
KNEES_X = [[-2.8, -0.3], [-2.8, -0.3], [0.3, 2.8], [0.3, 2.8]]  # ANYmal's: front knees back, hind forward

# name -> the copy, the keys `robot init` cannot infer from it (the key it names when refusing)
# and what it must find: leg tokens FR FL RR RL, how the feet are named, torque limits (3).
COPIES = {
    "go1": dict(model="unitree_go1/go1.xml", legs=("FR", "FL", "RR", "RL"), feet=("geom", "{leg}"),
                torque=(23.7, 23.7, 35.55)),
    "go2": dict(model="unitree_go2/go2.xml", legs=("FR", "FL", "RR", "RL"), feet=("geom", "{leg}"),
                torque=(23.7, 23.7, 45.43)),
    "a1": dict(model="unitree_a1/a1.xml", legs=("FR", "FL", "RR", "RL"), feet=("body", "{leg}_calf"),
               torque=(33.5, 33.5, 33.5)),
    "anymal_b": dict(model="anybotics_anymal_b/anymal_b.xml", given={"stance.knee": KNEES_X},
                     legs=("RF", "LF", "RH", "LH"), feet=("body", "{leg}_SHANK"), torque=(40.0, 40.0, 40.0)),
    "anymal_c": dict(model="anybotics_anymal_c/anymal_c.xml", given={"stance.knee": KNEES_X},
                     legs=("RF", "LF", "RH", "LH"), feet=("body", "{leg}_SHANK"), torque=(80.0, 80.0, 80.0)),
    "spot": dict(model="boston_dynamics_spot/spot.xml", legs=("fr", "fl", "hr", "hl"), feet=("body", "{leg}_lleg"),
                 torque=(1000.0, 1000.0, 1000.0)),
    # Barkour v0's servos state no force limit; its MJX variant's (and Barkour vB's) is 18 N m
    "barkour_v0": dict(model="google_barkour_v0/barkour_v0.xml", given={"limits.torque": [18.0, 18.0, 18.0]},
                       legs=("front_right", "front_left", "hind_right", "hind_left"),
                       feet=("body", "lower_leg_1to1_{leg}"), torque=(18.0, 18.0, 18.0)),
    "barkour_vb": dict(model="google_barkour_vb/barkour_vb.xml", legs=("front_right", "front_left", "hind_right",
                                                                         "hind_left"),
                       feet=("site", "foot_{leg}"), torque=(18.0, 18.0, 18.0)),
}


def model_path(name: str) -> Path:
    return FOLDER / COPIES[name]["model"]


def init_copies(folder: Path, names=tuple(COPIES)) -> dict[str, RobotInit]:
    """`robot init` on each copy (the keys it cannot infer given), descriptions written in ``folder``."""
    return {n: init_robot(model_path(n), folder / f"{n}.toml", overrides=COPIES[n].get("given")) for n in names}
