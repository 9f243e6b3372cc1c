"""Which tools of the window each generator capability enables, and the tooltip saying why one is off."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from engine.generators.base import Generator
    from explorer.main_window import MainWindow

#: window attribute -> the capability its tool needs
TOOLS: dict[str, str] = {
    "encode_action": "encode",
    "play_selection_action": "decode",
    "variations_action": "decode",
    "fit_mode_action": "decode",
    "export_selection_action": "decode",
    "trajectory": "end",
    "invert_action": "invert",
    "complete_action": "complete",
    "continue_action": "extend",
    "keep_going_action": "extend",
}
#: what an enabled tool does, as its tooltip (tools not named here have none)
TIPS: dict[str, str] = {
    "complete_action": "Ask the model for a few futures of the first motion shown, from the timeline's "
    "frame on, and play them side by side",
    "continue_action": "Extend the motions shown by the model, playing on from the current frame",
    "keep_going_action": "Extend the motions shown whenever playback nears their end",
}
#: latent-tools panel box -> the capability it needs
PANEL_TOOLS: dict[str, str] = {
    "truncate_box": "truncate",
    "mix_box": "mix",
    "crowd_box": "crowd",
    "invert_box": "invert",
    "edit_box": "edit",
}


def tool_widgets(window: MainWindow) -> dict[str, object]:
    """Every gated tool of ``window`` by its attribute name (menu actions and widgets)."""
    found = {name: getattr(window, name) for name in TOOLS}
    found["sample_button"] = window.mode_panel.sample_button
    found |= {name: getattr(window.latent_panel, name) for name in PANEL_TOOLS}
    return found


def gate_tools(window: MainWindow, generator: Generator) -> dict[str, str]:
    """Enable the tools ``generator`` can serve; disable the others with a tooltip saying why.

    Returns the disabled tools' attribute names with their reasons.
    """
    from engine.generators.base import refusal

    needs = TOOLS | PANEL_TOOLS | {"sample_button": "sample"}
    off = {}
    for name, tool in tool_widgets(window).items():
        capability = needs[name]
        ok = capability in generator.capabilities
        tool.setEnabled(ok)
        if not ok:
            off[name] = str(refusal(generator, capability))
        tool.setToolTip(off.get(name, TIPS.get(name, "")))
    return off
