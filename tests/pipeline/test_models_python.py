"""Trained models from Python (pipeline.models): posture()'s units, joint_angles(), a target of
the wrong dimension refused in one line, and a Figure that is a mapping label -> Model."""
import numpy as np
import pytest

import gbmodel
from pipeline.models import Figure, Model


def model_of(body: str, learner: dict | None = None) -> Model:
    spec = gbmodel.TrialSpec(body={"name": body}, learner={"name": "goal_babbling",
                                                           **(learner or {})}, epochs=20)
    r = gbmodel.run_trial(spec, np.random.default_rng(0))
    return Model(label="const1.0", spec=spec, M={0: r.M})


def test_a_radian_body_s_posture_is_its_joint_angles():
    m = model_of("arm5")
    x = m.body.target_set(m.size)[:4]
    assert not m.body.normalized
    np.testing.assert_array_equal(m.joint_angles(x), m.posture(x))


@pytest.mark.parametrize("body", ["icub", "icub_urdf"])
def test_a_normalised_body_s_joint_angles_are_its_commands_on_its_limits(body):
    m = model_of(body, {"radius": 0.1, "targets_per_epoch": 30, "steps": 10})
    b = m.body
    x = b.target_set(m.size)[:5]
    q = m.posture(x)
    assert b.normalized and np.abs(q).max() <= 1.5  # commands, not radians
    angles = m.joint_angles(x)
    expected = b.q_min + 0.5 * (np.clip(q, -1, 1) + 1.0) * (b.q_max - b.q_min)
    np.testing.assert_allclose(angles, expected, atol=1e-12)
    assert (angles >= b.q_min - 1e-12).all() and (angles <= b.q_max + 1e-12).all()
    # the angles drive the same hand as the commands (the DH offsets added back)
    np.testing.assert_allclose(b.joint_angles(q), angles + b.theta_offset, atol=1e-12)


@pytest.mark.parametrize("method", ["posture", "joint_angles", "reach"])
def test_a_target_of_the_wrong_dimension_is_one_line(method):
    m = model_of("arm5")
    with pytest.raises(ValueError) as err:
        getattr(m, method)([[0.1, 0.5, 0.2]])
    assert str(err.value) == "target of 3 coordinates: arm5 controls 2 (x, y)"


def test_a_figure_iterates_like_a_dict():
    a, b = model_of("arm5"), model_of("arm2")
    fig = Figure("f", {"A": a, "B": b})
    assert list(fig) == ["A", "B"] == fig.labels and len(fig) == 2
    assert dict(fig) == {"A": a, "B": b} and list(fig.items()) == [("A", a), ("B", b)]
    assert "A" in fig and "C" not in fig and fig.get("C") is None
    with pytest.raises(KeyError, match="f has no condition 'C'; it has \\['A', 'B'\\]"):
        fig["C"]
