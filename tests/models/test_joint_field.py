"""The tracker's position field learned with the FK (ctrkin.models.joint_field, TrainConfig.joint_field)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from ctrkin.errors import ModelError
from ctrkin.geometry import Registration
from ctrkin.models.frame import OuterFrame
from ctrkin.models.joint_field import FieldLayer, TrackerLoss, field_if_it_helps
from ctrkin.models.normalize import MinMax


def _setup(rng, rows: int = 400):
    """A frame with a tilted registration, local outputs, their frame angles and a prior."""
    frame = OuterFrame(Registration.from_rotvec(np.array([0.05, -0.08, 0.6]), np.array([3.0, -2.0, 40.0])))
    local = np.column_stack([rng.uniform(-30, 30, (rows, 2)), rng.uniform(20, 90, rows),
                             np.tile([1.0, 0.0, 0.0], (rows, 1))])
    outer = rng.uniform(-180, 180, rows)
    prior = np.column_stack([rng.normal(0, 2, (rows, 3)), np.zeros((rows, 3))])
    return frame, local, outer, prior


def test_the_loss_takes_outputs_to_the_tracker_frame_as_the_model_does(rng):
    frame, local, outer, prior = _setup(rng)
    y_norm = MinMax.fit(local - prior)
    world = frame.to_world(local, outer)
    loss = TrackerLoss.build(y_norm, outer, prior, world, frame.registration.rotation,
                             frame.registration.translation, np.arange(len(local)))
    yn = torch.from_numpy(y_norm.transform(local - prior).astype(np.float32))
    u = loss.unfielded(yn, torch.arange(len(local))).numpy()
    np.testing.assert_allclose(u, world[:, :3], rtol=0, atol=1e-3)      # float32 of ~100 mm
    zero = FieldLayer(world[:, :3].mean(0), 30.0)
    with torch.no_grad():
        assert float(loss.loss(zero, yn, yn, torch.arange(len(local)))) < 1e-5


def test_the_layer_and_the_position_field_it_becomes_agree(rng):
    layer = FieldLayer(np.array([1.0, -2.0, 50.0]), 25.0)
    with torch.no_grad():
        layer.coef.copy_(torch.from_numpy(rng.normal(0, 0.5, tuple(layer.coef.shape)).astype(np.float32)))
    p = rng.uniform(-30, 30, (200, 3)) + np.array([0.0, 0.0, 50.0])
    with torch.no_grad():
        moved = layer(torch.from_numpy(p.astype(np.float32))).numpy()
    pf = layer.position_field(0.1, 0.2)
    assert pf.degree == 3 and (pf.cv_rms_mm, pf.cv_rms_without_mm) == (0.1, 0.2)
    np.testing.assert_allclose(p + pf(p), moved, rtol=0, atol=1e-4)


def test_the_loss_drives_the_layer_to_a_field_the_data_has(rng):
    """Outputs held fixed, the targets warped by a smooth field of position: descending the loss on
    the layer alone recovers the warp at positions it was not fitted on."""
    frame, local, outer, _ = _setup(rng, 1500)
    world = frame.to_world(local, outer)[:, :3]

    def warp(p: np.ndarray) -> np.ndarray:
        u = (p - np.array([3.0, -2.0, 95.0])) / 40.0
        return np.column_stack([0.9 * u[:, 0] * u[:, 1] + 0.4, 0.6 * u[:, 2] ** 2, -0.5 * u[:, 0]])

    target = np.column_stack([world + warp(world), np.zeros((len(world), 3))])
    y_norm = MinMax.fit(local)
    fit, held = np.arange(1000), np.arange(1000, 1500)
    loss = TrackerLoss.build(y_norm, outer, None, target, frame.registration.rotation,
                             frame.registration.translation, fit)
    yn = torch.from_numpy(y_norm.transform(local).astype(np.float32))
    centre = world[fit].mean(0)
    layer = FieldLayer(centre, float(np.sqrt(((world[fit] - centre) ** 2).sum(1).mean())))
    opt = torch.optim.Adam(layer.parameters(), lr=0.02)
    rows = torch.from_numpy(fit)
    for _ in range(800):
        opt.zero_grad()
        loss.loss(layer, yn[fit], yn[fit], rows).backward()
        opt.step()
    with torch.no_grad():
        learned = layer(torch.from_numpy(world[held].astype(np.float32))).numpy() - world[held]
    err = np.sqrt(np.mean(np.sum((learned - warp(world[held])) ** 2, axis=1)))
    size = np.sqrt(np.mean(np.sum(warp(world[held]) ** 2, axis=1)))
    assert err < 0.1 * size


def test_a_field_is_kept_only_where_it_lowers_the_held_out_error(rng):
    """Where the measured positions hold the layer's warp it is kept; where they hold none (an optical
    tracker) a layer that learned one from noise is not."""
    p = rng.uniform(-30, 30, (300, 3)) + np.array([0.0, 0.0, 90.0])
    layer = FieldLayer(np.array([0.0, 0.0, 90.0]), 30.0)
    with torch.no_grad():
        layer.coef.copy_(torch.from_numpy(rng.normal(0.0, 0.5, tuple(layer.coef.shape)).astype(np.float32)))
        warped = layer(torch.from_numpy(p.astype(np.float32))).numpy().astype(np.float64)
    kept, with_mm, without_mm = field_if_it_helps(layer, p, warped + rng.normal(0.0, 0.05, p.shape))
    assert kept is not None and with_mm < 0.1 < without_mm
    assert (kept.cv_rms_mm, kept.cv_rms_without_mm) == (with_mm, without_mm)
    dropped, with_mm, without_mm = field_if_it_helps(layer, p, p + rng.normal(0.0, 0.05, p.shape))
    assert dropped is None and with_mm > without_mm


def test_a_joint_field_fk_keeps_its_field_in_the_frame_and_streams_what_it_predicts(sweeps, tmp_path):
    from ctrkin.inference import Kinematics
    from ctrkin.training import TrainConfig, train

    cfg = TrainConfig(task="fk", max_epochs=2, threads=1, target_frame="outer", joint_field=True,
                      options={"structure": "L16|D16"})
    res = train(sweeps, cfg, tmp_path / "fk", progress=False)
    kin = Kinematics.load(tmp_path / "fk")                  # the weights hold the network alone
    frame = kin.predictor.frame
    assert frame is not None and frame.field is not None and frame.field.degree == 3 and kin.fused
    assert not any("joint_field" in k for k in torch.load(tmp_path / "fk" / "weights.pt").keys())
    a, b = sweeps.sequence_bounds()[0]
    q = sweeps.joints()[a:b]
    batch = np.asarray(kin.predict(q))
    kin.reset()
    np.testing.assert_allclose(batch, np.array([kin.step(r) for r in q]), rtol=0, atol=1e-4)
    assert np.isfinite(res.metrics["val"]["vs_measured"]["position_mm_rmse"])
    assert res.metrics["joint_field"]["kept"]           # the metrics say why the frame holds it
    said: list[str] = []            # a finished run continues from its checkpoint, the layer's weights too
    more = train(sweeps, replace(cfg, max_epochs=3), tmp_path / "fk", progress=False, log=said.append)
    assert any("resuming" in m for m in said) and more.metrics["training"]["epochs"] == 3
    again = Kinematics.load(tmp_path / "fk").predictor.frame
    train(sweeps, replace(cfg, max_epochs=3), tmp_path / "straight", progress=False)
    straight = Kinematics.load(tmp_path / "straight").predictor.frame
    assert again is not None and again.field is not None
    assert straight is not None and straight.field is not None and np.abs(straight.field.coef).max() > 0
    np.testing.assert_array_equal(again.field.coef, straight.field.coef)     # as if never stopped
    with pytest.raises(ModelError, match="joint_field"):
        TrainConfig(task="fk", target_frame="tracker", joint_field=True)
