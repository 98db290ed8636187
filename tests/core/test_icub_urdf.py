"""The iCub body's forward kinematics against the robot's official URDF model.

`make_body("icub")` computes the palm position of iCub's torso + right arm (10 DOF) from the
DH "right arm v1" table of iKin (see ../shared/reference/icub-right-arm.md), written by hand
into gbmodel. A typo in that table (a length, a twist, a theta offset, a joint limit, the order
of the joints or of the normalisation) would give a plausible but wrong arm, and the learning
results would still look fine. So this file checks the hand-written chain against an independent
source: the URDF of model `iCubLisboa01` from robotology's `icub-models` package (a v1-arm
robot), evaluated with `yourdfpy`. There, iKin's palm frame is called `r_hand_dh_frame`, and the
root frame is `root_link`; the URDF joint angles use iKin's sign convention.

Checked:
  * 200 random postures, drawn uniformly in the normalised command box [-1, 1]^10, plus the
    two corners q = -1 and q = +1: the palm position agrees with the URDF within 0.5 mm (the
    two models are known to differ by about 0.16 mm, a fixed rounding offset of the shoulder
    in the URDF's chest frame).
  * The robot's start-up posture puts the palm near (-0.298, 0.210, 0.029) m.

The normalised-to-radian map is written out here again from the reference table (not taken
from gbmodel), so the test also checks gbmodel's joint limits and normalisation. The URDF's
meshes are not loaded: the test needs no network and runs in about a second.

Required test dependencies (PyPI): `yourdfpy`, `icub-models`. They are imported normally, so
the test fails rather than skips when they are missing.
"""
import icub_models
import numpy as np
import pytest
import yourdfpy

from gbmodel.bodies import make_body

URDF_MODEL = "iCubLisboa01"
ROOT_FRAME = "root_link"
PALM_FRAME = "r_hand_dh_frame"

# Chain order of the DH table = order of gbmodel's commands; these are also the URDF's names.
JOINTS = (
    "torso_pitch", "torso_roll", "torso_yaw",
    "r_shoulder_pitch", "r_shoulder_roll", "r_shoulder_yaw",
    "r_elbow",
    "r_wrist_prosup", "r_wrist_pitch", "r_wrist_yaw",
)
# Joint limits of the right arm v1 table [deg]; command -1 -> min, +1 -> max.
# (The URDF's own limits agree, except r_shoulder_pitch, whose URDF minimum is -95.0 deg;
# yourdfpy does not clip, so the URDF is still evaluated at the table's -95.5.)
LIMITS_DEG = np.array([
    [-22.0, 84.0], [-39.0, 39.0], [-59.0, 59.0],
    [-95.5, 5.0], [0.0, 160.8], [-37.0, 100.0],
    [5.5, 106.0],
    [-50.0, 50.0], [-65.0, 10.0], [-25.0, 25.0],
])

TOLERANCE_URDF = 0.5e-3  # [m]
N_RANDOM = 200
SEED = 20100101


def to_radians(q: np.ndarray) -> np.ndarray:
    """Joint angles [rad] for normalised commands q in [-1, 1]."""
    lo, hi = np.deg2rad(LIMITS_DEG).T
    return lo + 0.5 * (np.asarray(q) + 1.0) * (hi - lo)


def to_commands(angles_deg: np.ndarray) -> np.ndarray:
    """Normalised commands for joint angles [deg] (inverse of to_radians)."""
    lo, hi = LIMITS_DEG.T
    return 2.0 * (np.asarray(angles_deg, float) - lo) / (hi - lo) - 1.0


@pytest.fixture(scope="module")
def urdf() -> yourdfpy.URDF:
    path = icub_models.get_model_file(URDF_MODEL)
    return yourdfpy.URDF.load(
        path,
        build_scene_graph=True,
        load_meshes=False,
        build_collision_scene_graph=False,
        load_collision_meshes=False,
    )


def urdf_palm(urdf: yourdfpy.URDF, angles: np.ndarray) -> np.ndarray:
    """Palm position [m] in the root frame from the URDF, for joint angles (10,) [rad]."""
    urdf.update_cfg(dict(zip(JOINTS, angles)))
    return urdf.get_transform(frame_to=PALM_FRAME, frame_from=ROOT_FRAME)[:3, 3]


def test_urdf_has_the_chain(urdf):
    missing = [j for j in JOINTS if j not in urdf.joint_map]
    assert not missing, f"{URDF_MODEL} has no joints {missing}"
    for frame in (ROOT_FRAME, PALM_FRAME):
        assert frame in urdf.link_map, f"{URDF_MODEL} has no frame {frame}"


def test_forward_matches_urdf(urdf):
    rng = np.random.default_rng(SEED)
    q = np.vstack([rng.uniform(-1.0, 1.0, size=(N_RANDOM, len(JOINTS))),
                   -np.ones(len(JOINTS)), np.ones(len(JOINTS))])

    expected = np.array([urdf_palm(urdf, a) for a in to_radians(q)])
    got = make_body("icub").forward(q)

    assert got.shape == expected.shape
    dev = np.linalg.norm(got - expected, axis=1)
    worst = int(np.argmax(dev))
    assert dev.max() < TOLERANCE_URDF, (
        f"palm differs from the {URDF_MODEL} URDF by up to {dev.max() * 1e3:.3f} mm "
        f"(mean {dev.mean() * 1e3:.3f} mm, {np.sum(dev >= TOLERANCE_URDF)} of {len(q)} postures "
        f"over {TOLERANCE_URDF * 1e3} mm); worst at q = {np.round(q[worst], 3).tolist()}: "
        f"gbmodel {np.round(got[worst], 5).tolist()} m, URDF {np.round(expected[worst], 5).tolist()} m"
    )
    # a single posture (shape (10,)) gives the same as its row of the batch
    np.testing.assert_allclose(make_body("icub").forward(q[0]), got[0], rtol=0, atol=1e-12)


def test_startup_posture():
    # torso 0; shoulder pitch/roll/yaw -30, 30, 0; elbow 45; wrist 0, 0, 0 [deg]
    q = to_commands([0, 0, 0, -30, 30, 0, 45, 0, 0, 0])
    palm = make_body("icub").forward(q)
    expected = np.array([-0.298, 0.210, 0.029])
    assert np.linalg.norm(palm - expected) < 2e-3, (
        f"start-up palm at {np.round(palm, 4).tolist()} m, expected near {expected.tolist()} m "
        f"(off by {np.linalg.norm(palm - expected) * 1e3:.2f} mm)"
    )


# ---- the iCub built from its URDF (conf/body/icub_urdf.yaml) -------------------------

def test_the_urdf_icub_is_the_urdf(urdf):
    """make_body("icub_urdf") computes the URDF's palm exactly (the compiled chain)."""
    q = np.random.default_rng(SEED).uniform(-1.0, 1.0, size=(50, len(JOINTS)))
    expected = np.array([urdf_palm(urdf, a) for a in to_radians(q)])
    np.testing.assert_allclose(make_body("icub_urdf").forward(q), expected, rtol=0, atol=1e-9)


def test_the_urdf_icub_beside_the_dh_icub():
    """The two iCubs differ by the URDF's rounding only: 0.16 mm over random postures."""
    q = np.random.default_rng(SEED).uniform(-1.0, 1.0, size=(N_RANDOM, len(JOINTS)))
    dev = np.linalg.norm(make_body("icub_urdf").forward(q) - make_body("icub").forward(q), axis=1)
    assert 0.10e-3 < dev.max() < 0.20e-3, dev.max()
    np.testing.assert_array_equal(make_body("icub_urdf").home, make_body("icub").home)
