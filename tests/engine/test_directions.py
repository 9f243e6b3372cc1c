"""Edit directions: known directions recovered from synthetic codes, and edits that change the motion a
model decodes the way their name says, for every kind with a bank; the latent CLI commands."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from engine.cli import main
from engine.errors import ConfigError
from engine.generators import CapabilityError, SampleRequest, open_generator
from engine.latent.directions import attribute_direction, fit_directions, label_directions
from engine.motion.formats import write_motion
from engine.motion.npz import read_npz
from engine.motion.ops import motion_energy

pytestmark = pytest.mark.usefixtures("torch_single_thread")


def test_a_label_shifted_along_one_axis_gets_that_axis() -> None:
    rng = np.random.default_rng(0)
    codes = rng.standard_normal((300, 6))
    labels = np.array(["a", "b", "c"])[rng.integers(0, 3, 300)]
    codes[labels == "b", 2] += 4.0  # two standard deviations either side of the boundary: 98 % separable
    meta = [{"style": str(v)} for v in labels] + [{}] * 5  # codes without the key are left out
    codes = np.concatenate([codes, rng.standard_normal((5, 6))])
    found = {d.name: d for d in label_directions(codes, meta, "style")}
    assert set(found) == {"style=a", "style=b", "style=c"}
    b = found["style=b"]
    assert abs(b.normal[2]) > 0.95 and b.normal[2] > 0  # towards the label
    assert b.score > 0.9 and b.n_codes == 300
    np.testing.assert_allclose(np.linalg.norm(b.normal), 1.0, atol=1e-6)
    assert found["style=a"].score < 0.8  # a label with no direction scores near chance


def test_a_scalar_attribute_gets_its_gradient_and_apply_moves_by_spreads() -> None:
    rng = np.random.default_rng(1)
    codes = rng.standard_normal((200, 5))
    truth = np.array([1.0, -2.0, 0.0, 0.5, 0.0])
    d = attribute_direction(codes, codes @ truth + 0.01 * rng.standard_normal(200), "speed")
    np.testing.assert_allclose(d.normal, truth / np.linalg.norm(truth), atol=0.01)
    assert d.score > 0.99
    moved = d.apply(codes[:3], 2.0)
    np.testing.assert_allclose((moved - codes[:3]) @ d.normal, 2.0 * d.scale, rtol=1e-5)
    stacked = d.apply(np.tile(codes[0], 3), 1.0).reshape(3, 5)  # W+: every layer moves alike
    np.testing.assert_allclose(stacked - codes[0], np.tile(d.scale * d.normal, (3, 1)), atol=1e-5)
    with pytest.raises(ConfigError, match="codes have 7 values"):
        d.apply(np.zeros(7), 1.0)
    with pytest.raises(ConfigError, match="no direction"):
        attribute_direction(codes, np.zeros(200), "flat")


def test_fit_directions_names_every_direction() -> None:
    rng = np.random.default_rng(2)
    codes = rng.standard_normal((60, 4))
    meta = [{"style": "x" if i % 2 else "y"} for i in range(60)]
    found = fit_directions(codes, meta, attributes={"energy": codes[:, 0]})
    assert set(found) == {"style=x", "style=y", "energy"}


@pytest.mark.parametrize("fixture", ["tiny_model_dir", "tiny_modi_dir"])
def test_the_energy_direction_makes_decoded_motions_move_more(fixture: str, request) -> None:
    generator = open_generator(request.getfixturevalue(fixture))
    bank = generator.bank
    directions = generator.edit_directions
    assert {"speed", "energy"} <= set(directions)
    assert any(name.startswith("style=") for name in directions)  # the procedural clips' styles
    rows = np.linspace(0, len(bank.codes) - 1, 12).astype(int)
    more = 0
    for i in rows:
        action = None if generator.action_names is None else bank.action_names[int(bank.actions[i])]
        up = generator.edit(bank.codes[i], action, "energy", 3.0).motion.joints  # the panel's full range
        down = generator.edit(bank.codes[i], action, "energy", -3.0).motion.joints
        more += motion_energy(up[None], generator.fps)[0] > motion_energy(down[None], generator.fps)[0]
    assert more >= 10, f"{more} of 12 edits raised the energy"
    with pytest.raises(ConfigError, match="no edit direction 'style=nope'"):
        generator.edit(bank.codes[0], None if generator.action_names is None else bank.action_names[0],
                       "style=nope", 1.0)  # fmt: skip


def test_a_model_without_a_bank_refuses_edits(tiny_a2m_old_dir: Path) -> None:
    generator = open_generator(tiny_a2m_old_dir)
    with pytest.raises(CapabilityError, match="cannot edit along semantic directions"):
        _ = generator.edit_directions


def test_cli_edit_mix_crowd_and_invert(tiny_modi_dir: Path, tmp_path: Path, capsys) -> None:
    generator = open_generator(tiny_modi_dir)
    model = ["--model", str(tiny_modi_dir)]
    assert main(["edit", *model, "--list"]) == 0
    listed = capsys.readouterr().out
    assert "energy\tscore" in listed and "style=" in listed
    out = tmp_path / "edit"
    assert main(["edit", *model, "--code", "i3", "--direction", "energy", "--amount", "2", "--steps", "3",
                 "--out", str(out)]) == 0  # fmt: skip
    files = sorted(out.glob("*.npz"))
    assert len(files) == 3
    [start] = generator.decode(generator.bank.codes[3][None])
    np.testing.assert_allclose(read_npz(files[0]).joints, start.joints, atol=1e-5)
    expected = generator.edit(generator.bank.codes[3], None, "energy", 2.0).motion.joints
    np.testing.assert_allclose(read_npz(files[-1]).joints, expected, atol=1e-5)

    assert main(["mix", *model, "--coarse", "i1", "--fine", "i2", "--split", "1", "--out",
                 str(tmp_path / "mix.npz")]) == 0  # fmt: skip
    mixed = generator.mix(generator.bank.codes[1], generator.bank.codes[2], 1).motion.joints
    np.testing.assert_allclose(read_npz(tmp_path / "mix.npz").joints, mixed, atol=1e-5)

    assert main(["crowd", *model, "--code", "i0", "--n", "4", "--sigma", "0.2", "--out",
                 str(tmp_path / "crowd")]) == 0  # fmt: skip
    crowd = sorted((tmp_path / "crowd").glob("*.npz"))
    assert len(crowd) == 4
    assert not np.allclose(read_npz(crowd[0]).joints, read_npz(crowd[1]).joints)

    clip = generator.sample(SampleRequest(None, 1, 3))[0].motion
    write_motion(clip, tmp_path / "clip.npz")
    capsys.readouterr()
    assert main(["invert", *model, str(tmp_path / "clip.npz"), "--steps", "60", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["space"] == "W+" and len(report["code"]) == 32 * generator.n_styles
    assert 0.0 <= report["error_m"] < 0.2


def test_cli_latent_commands_refuse_what_a_kind_lacks(tiny_model_dir: Path, capsys) -> None:
    assert (
        main(["mix", "--model", str(tiny_model_dir), "--coarse", "i0", "--fine", "i1", "--out", "x.npz"]) == 1
    )
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "this odmo model cannot mix styles" in err
    argv = ["edit", "--model", str(tiny_model_dir), "--code", "i0", "--direction", "energy", "--out", "x.npz"]
    assert main(argv) == 1
    assert "name an --action" in capsys.readouterr().err
    assert main(["edit", "--model", str(tiny_model_dir), "--list"]) == 0
    assert "speed\tscore" in capsys.readouterr().out


def test_edit_effect_sees_a_style_edit_with_a_style_classifier(
    tiny_model_dir: Path, procedural_clips, tmp_path: Path
) -> None:
    import dataclasses

    from engine.metrics.classifier import train_classifier
    from engine.metrics.edits import edit_effect
    from tests.fixtures.procedural import PROCEDURAL_ACTIONS

    styles = sorted({c.meta["style"] for c in procedural_clips})
    relabelled = [dataclasses.replace(c, action=c.meta["style"]) for c in procedural_clips]
    style_clf = train_classifier(relabelled, styles, tmp_path / "style", epochs=4, batch_size=16, window=40)
    action_clf = train_classifier(procedural_clips, PROCEDURAL_ACTIONS, tmp_path / "act", epochs=4,
                                  batch_size=16, window=40)  # fmt: skip
    generator = open_generator(tiny_model_dir)
    bank = generator.bank
    target = styles[0]
    rows = [i for i, m in enumerate(bank.meta) if m.get("style") != target][:12]
    actions = [bank.action_names[int(bank.actions[i])] for i in rows]
    effect = edit_effect(generator, bank.codes[rows], actions, f"style={target}", 3.0, style_clf, action_clf)
    assert effect.n == 12 and 0.0 <= effect.kept <= 1.0
    back = edit_effect(generator, bank.codes[rows], actions, f"style={target}", -3.0, style_clf, action_clf)
    assert effect.after > back.after  # towards the style raises its probability more than away from it
    with pytest.raises(ConfigError, match="the style classifier knows"):
        edit_effect(generator, bank.codes[rows], actions, "style=nope", 1.0, style_clf, action_clf)


def test_scores_do_not_depend_on_the_order_codes_are_stored_in() -> None:
    rng = np.random.default_rng(4)
    codes = rng.standard_normal((300, 5))
    values = codes @ np.array([1.0, 0.5, 0.0, 0.0, -1.0])
    order = np.argsort(values)  # a bank stored by clip runs through its attribute in order
    assert attribute_direction(codes[order], values[order], "speed").score > 0.99
    labels = np.where(codes[:, 0] > 0, "a", "b")
    meta = [{"style": str(v)} for v in labels[np.argsort(labels)]]
    [a, _] = label_directions(codes[np.argsort(labels)], meta, "style")
    assert a.score > 0.9
