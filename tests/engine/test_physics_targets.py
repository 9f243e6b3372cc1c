"""The model card's per-action verdicts on issue 18's targets (bench/model_card.py)."""

from bench.model_card import physics_targets


def _side(**figures: float) -> dict[str, dict[str, float]]:
    return {k: {"mean": v, "ci95": 0.0} for k, v in figures.items()}


def _action(sync: tuple[float, float], feet: tuple[float, float], hands: float = 1.0) -> dict:
    """One action's report: foot sync and foot speed (generated, real), generated hand speed (real 1)."""
    base = {"bone_length_cv": 0.001, "foot_skate_m_s": 0.1, "floor_penetration": 0.0, "float_share": 0.0}
    gen = base | {"foot_sync": sync[0], "foot_speed_m_s": feet[0], "hand_speed_m_s": hands}
    real = base | {"foot_sync": sync[1], "foot_speed_m_s": feet[1], "hand_speed_m_s": 1.0}
    return {"generated": _side(**gen), "real": _side(**real)}


def test_feet_are_judged_on_alternation_only_where_real_feet_step() -> None:
    report = {
        "per_action": {
            # a walk whose feet step together (+0.1) where real ones alternate (−0.6): missed
            "walk": _action((0.1, -0.6), (1.2, 1.3)),
            # a run within 0.3 of real: met
            "run": _action((-0.6, -0.85), (2.7, 3.0)),
            # standing feet (real 5 mm/s) have no gait: their correlation of sway is not judged
            "wave": _action((0.6, 0.96), (0.0, 0.005)),
            # hands at 0.7× real speed: missed on hand speed only
            "raise": _action((0.9, 0.95), (0.0, 0.004), hands=0.7),
        }
    }
    lines = {line.split(":")[0]: line for line in physics_targets(report)}
    feet = next(v for k, v in lines.items() if k.startswith("- feet alternating"))
    assert feet.endswith("3/4 actions — missed (walk).")
    assert lines["- mean hand speed ≥ 0.8× real"].endswith("3/4 actions — missed (raise).")
    assert lines["- worst-bone length variation ≤ 1 %"].endswith("4/4 actions — met.")


def test_feet_pointing_backwards_are_judged_against_real_where_real_ones_travel() -> None:
    walk, run, wave = (
        _action((-0.6, -0.6), (1.2, 1.3)),
        _action((-0.8, -0.85), (2.7, 3.0)),
        _action((0.9, 0.96), (0, 0)),
    )
    walk["generated"] |= _side(feet_backward=0.99)  # the bundled model's walks: their feet turned round
    walk["real"] |= _side(feet_backward=0.001)
    run["generated"] |= _side(feet_backward=0.04)  # within 5 points of real
    run["real"] |= _side(feet_backward=0.0)
    lines = physics_targets({"per_action": {"walk": walk, "run": run, "wave": wave}})  # waves do not travel
    feet = next(line for line in lines if line.startswith("- feet pointing the way they go"))
    assert feet.endswith("2/3 actions — missed (walk).")


def test_feet_popping_off_the_floor_faster_than_real_ones_miss() -> None:
    walk, run, wave = (
        _action((-0.6, -0.6), (1.2, 1.3)),
        _action((-0.8, -0.85), (2.7, 3.0)),
        _action((0.9, 0.96), (0, 0)),
    )
    walk["generated"] |= _side(foot_pop_m_s=1.18)  # feet released from the floor in one frame
    walk["real"] |= _side(foot_pop_m_s=0.91)
    run["generated"] |= _side(foot_pop_m_s=2.8)
    run["real"] |= _side(foot_pop_m_s=2.81)
    wave["generated"] |= _side(foot_pop_m_s=0.03)  # standing feet: under the 0.1 m/s floor
    wave["real"] |= _side(foot_pop_m_s=0.01)
    lines = physics_targets({"per_action": {"walk": walk, "run": run, "wave": wave}})
    pop = next(line for line in lines if line.startswith("- feet lifting and landing"))
    assert pop.endswith("2/3 actions — missed (walk).")


def test_a_body_lowered_onto_drawn_up_legs_misses_its_height_and_old_reports_are_not_judged() -> None:
    walk, run = _action((-0.6, -0.6), (1.2, 1.3)), _action((-0.8, -0.85), (2.7, 3.0))
    walk["generated"] |= _side(pelvis_height_m=0.86)  # 6 % under real: met
    walk["real"] |= _side(pelvis_height_m=0.913)
    run["generated"] |= _side(pelvis_height_m=0.48)  # a run crouched onto its tucked feet (stop 47)
    run["real"] |= _side(pelvis_height_m=0.92)
    lines = physics_targets({"per_action": {"walk": walk, "run": run}})
    height = next(line for line in lines if line.startswith("- body at its real height"))
    assert height.endswith("1/2 actions — missed (run).")
    before = physics_targets({"per_action": {"walk": _action((-0.6, -0.6), (1.2, 1.3))}})
    assert not any(line.startswith("- body at its real height") for line in before)
