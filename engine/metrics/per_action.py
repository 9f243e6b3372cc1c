"""The per-action figures every report shows, generated against real: one list of columns, one table."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class PerActionColumn:
    """One figure of the per-action table: its metric key, a short and a full heading, a value format."""

    metric: str
    short: str
    heading: str
    fmt: str


PER_ACTION_COLUMNS = (
    PerActionColumn("accuracy", "accuracy", "accuracy", "{:.2f}"),
    PerActionColumn("bone_length_cv", "bone cv", "bone cv", "{:.2%}"),
    PerActionColumn("foot_skate_m_s", "skate", "planted-foot speed (m/s)", "{:.3f}"),
    PerActionColumn("foot_pop_m_s", "foot pop", "foot pop (m/s)", "{:.2f}"),
    PerActionColumn("floor_penetration", "under floor", "frames under floor", "{:.2%}"),
    PerActionColumn("float_share", "floating", "floating clips", "{:.0%}"),
    PerActionColumn("hand_speed_m_s", "hand speed", "hand speed (m/s)", "{:.2f}"),
    PerActionColumn("hand_amplitude_m", "hand amp.", "hand amp. (m)", "{:.3f}"),
    PerActionColumn("late_hand_speed_m_s", "late hand", "late hand speed (m/s)", "{:.2f}"),
    PerActionColumn("hand_rhythm_hz", "hand rhythm", "hand rhythm (Hz)", "{:.2f}"),
    PerActionColumn("foot_speed_m_s", "foot speed", "foot speed (m/s)", "{:.2f}"),
    PerActionColumn("foot_amplitude_m", "foot amp.", "foot amp. (m)", "{:.3f}"),
    PerActionColumn("jerk_m_s3", "jerk", "jerk (m/s³)", "{:.0f}"),
    PerActionColumn("pelvis_height_m", "pelvis", "pelvis height (m)", "{:.2f}"),
    PerActionColumn("heading_error_deg", "heading", "heading (°)", "{:.1f}"),
    PerActionColumn("torso_twist_deg", "twist", "twist (°)", "{:.1f}"),
    PerActionColumn("foot_sync", "foot sync", "foot sync (r)", "{:+.2f}"),
    PerActionColumn("feet_backward", "feet back", "feet backward", "{:.0%}"),
    PerActionColumn("joint_range_excess", "joint range", "joint range", "{:.0%}"),
)


def present_columns(per_action: dict[str, Any]) -> list[PerActionColumn]:
    """The columns whose metric the real side of some action holds."""
    return [c for c in PER_ACTION_COLUMNS if any(c.metric in row["real"] for row in per_action.values())]


def per_action_cell(row: dict[str, Any], column: PerActionColumn) -> str:
    """``generated / real`` means of one action's ``row`` for ``column`` ("–" where a side lacks it)."""
    gen, real = row["generated"].get(column.metric), row["real"].get(column.metric)
    if gen is None or real is None:
        return "–"
    return f"{column.fmt.format(gen['mean'])} / {column.fmt.format(real['mean'])}"


def per_action_markdown(per_action: dict[str, Any]) -> list[str]:
    """Markdown rows of the per-action table (an evaluation's ``per_action``), generated / real."""
    columns = present_columns(per_action)
    if not columns:
        return []
    rows = ["| action | " + " | ".join(c.heading for c in columns) + " |"]
    rows.append("|---|" + "|".join("---" for _ in columns) + "|")
    rows += [
        f"| {action} | " + " | ".join(per_action_cell(row, c) for c in columns) + " |"
        for action, row in per_action.items()
    ]
    return rows
