"""The one per-action table: its columns, cells and Markdown, as cards, RESULTS.md and `odmo eval` show it."""

from __future__ import annotations

from engine.cli.eval_commands import format_per_action
from engine.metrics.per_action import PER_ACTION_COLUMNS, per_action_markdown, present_columns


def _side(**means: float) -> dict[str, dict[str, float]]:
    return {k: {"mean": v, "ci95": 0.0} for k, v in means.items()}


PER_ACTION = {
    "wave": {
        "generated": _side(accuracy=0.5, late_hand_speed_m_s=0.04, bone_length_cv=0.0123),
        "real": _side(accuracy=1.0, late_hand_speed_m_s=0.931, bone_length_cv=0.001),
    },
    "walk": {
        "generated": _side(accuracy=0.75),
        "real": _side(accuracy=0.9, late_hand_speed_m_s=1.6),
    },
}


def test_columns_are_those_the_real_side_holds_in_table_order() -> None:
    assert [c.metric for c in present_columns(PER_ACTION)] == [
        "accuracy",
        "bone_length_cv",
        "late_hand_speed_m_s",
    ]
    assert len({c.metric for c in PER_ACTION_COLUMNS}) == len(PER_ACTION_COLUMNS)


def test_markdown_rows_read_generated_over_real() -> None:
    assert per_action_markdown(PER_ACTION) == [
        "| action | accuracy | bone cv | late hand speed (m/s) |",
        "|---|---|---|---|",
        "| wave | 0.50 / 1.00 | 1.23% / 0.10% | 0.04 / 0.93 |",
        "| walk | 0.75 / 0.90 | – | – |",
    ]
    assert per_action_markdown({}) == []


def test_the_cli_shows_the_same_cells() -> None:
    text = format_per_action({"per_action": PER_ACTION})
    lines = text.splitlines()
    assert lines[0].startswith("per action, generated / real")
    assert lines[1].split() == ["action", "accuracy", "bone", "cv", "late", "hand"]
    assert lines[2].split() == ["wave", "0.50", "/", "1.00", "1.23%", "/", "0.10%", "0.04", "/", "0.93"]
    assert lines[3].split() == ["walk", "0.75", "/", "0.90", "–", "–"]
    assert format_per_action({"per_action": {}}) == ""
