"""Edit sliders in the latent-tools panel: one per edit direction of the loaded model, applied to the
last clicked (picked) code.

The directions are found in a task when a model that edits is loaded (finding them decodes every bank
code once). Several sliders off zero move the code along each of their directions in turn (the sum of
amount · spread · normal), decoded as a frozen request of the decode worker (the newest wins); the edited
motion plays before the unedited one. Picking another code puts every slider back to zero.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from explorer.requests import EditDecode

if TYPE_CHECKING:
    from engine.generators.base import Generator
    from engine.latent.directions import EditDirection
    from explorer.controller import Controller
    from explorer.workers import Cancel, Progress


def score_text(direction: EditDirection) -> tuple[str, str]:
    """The short score of ``direction`` beside its slider and the tooltip saying what it measures."""
    n = direction.n_codes
    if "=" in direction.name:  # a metadata label ("style=elderly"); the others are attributes
        return (
            f"acc {direction.score:.2f}",
            f"Cross-validated balanced accuracy of the linear SVM that separates {direction.name} from "
            f"the other labels ({n} codes; 0.5 is chance). Amounts are spreads of the codes along it.",
        )
    return (
        f"R² {direction.score:.2f}",
        f"Cross-validated R² of the ridge regression of {direction.name} on the codes ({n} codes; "
        "0 or less: no better than the mean). Amounts are spreads of the codes along it.",
    )


class Editing:
    """The edit sliders of controller ``c``'s latent-tools panel."""

    def __init__(self, c: Controller) -> None:
        self.c = c
        self.searches = 0  # id of the newest search for directions
        panel = c.window.latent_panel
        panel.editChanged.connect(self.set_amount)
        panel.editReset.connect(self.reset)
        ev = c.state.events
        ev.edit_directions.connect(self._directions_changed)
        ev.edits.connect(self._edits_changed)
        ev.picked.connect(lambda _p: setattr(c.state, "edits", ()))
        c.modelLoaded.connect(self._model_changed)

    def _model_changed(self, generator: Generator) -> None:
        self.searches += 1
        search = self.searches
        self.c.state.edits = ()
        self.c.state.edit_directions = ()
        panel = self.c.window.latent_panel
        if "edit" not in generator.capabilities:
            panel.set_edit_note("")
            return
        n = len(generator.bank.codes)
        panel.set_edit_note(f"Finding the edit directions (decoding the {n} bank codes once)…")

        def job(_p: Progress, _c: Cancel) -> tuple[EditDirection, ...]:
            return tuple(generator.edit_directions.values())

        def current() -> bool:
            return search == self.searches and self.c.state.model is generator

        def done(found: tuple[EditDirection, ...]) -> None:
            if current():
                self.c.state.edit_directions = found

        def failed(why: BaseException | str) -> None:
            if current():
                panel.set_edit_note(f"No edit directions: {why}")
                self.c.window.show_status(f"No edit directions: {why}")

        task = self.c.tasks.run("Finding edit directions", job, done, failed)
        task.cancelled.connect(lambda: failed("finding them was cancelled; open the model again to retry"))

    def _directions_changed(self, found: tuple[EditDirection, ...]) -> None:
        panel = self.c.window.latent_panel
        panel.set_directions([(d.name, *score_text(d)) for d in found])
        if found:
            panel.set_edit_note(
                "Slide to move the last clicked code along a direction (in spreads of the bank codes); "
                "the edited motion plays beside the unedited one."
            )

    def set_amount(self, name: str, amount: float) -> None:
        """Set the amount (spreads) of direction ``name``'s edit; the other sliders keep theirs."""
        amounts = dict(self.c.state.edits) | {name: float(amount)}
        order = [d.name for d in self.c.state.edit_directions]
        self.c.state.edits = tuple((n, amounts[n]) for n in order if amounts.get(n, 0.0) != 0.0)

    def _edits_changed(self, edits: tuple[tuple[str, float], ...]) -> None:
        self.c.window.latent_panel.set_amounts(dict(edits))
        if edits:
            self._decode(edits)

    def reset(self) -> None:
        """Every slider to zero; the unedited code plays."""
        self.c.state.edits = ()
        self._decode(())

    def _decode(self, edits: tuple[tuple[str, float], ...]) -> None:
        if self.c.refuse("edit"):
            return
        if not self.c.state.picked:
            self.c.window.show_status(
                "Click a code on the map first: the sliders edit the last clicked code."
            )
            return
        pick = self.c.state.picked[-1]
        by_name = {d.name: d for d in self.c.state.edit_directions}
        steps = tuple((by_name[n], a) for n, a in edits)
        self.c.decoder.submit(EditDecode(self.c.generator, pick.code, pick.action, pick.label, steps).run)
