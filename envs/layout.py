"""Observation layouts: each declared once, as data, and used by the compiled step, the Python
path and the env's docstring alike.

An :class:`ObsField` names one entry of a flat observation, its bounds and its meaning (with
units). A task's ``LAYOUT`` is a tuple of them, in order; the env docstrings render it with
:func:`layout_table`, the observation space takes its bounds, and the code that fills the
observation addresses it by field name (the control envs' compiled step through the constants of
``envs.fast.CONTROL_OBS``, built from :data:`CONTROL_LAYOUT`; the one-strike envs by name in
``observe``), so neither the docs nor the order can drift from the code.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

__all__ = ["CONTROL_LAYOUT", "SPEED_SCALE", "SPIN_SCALE", "ObsField", "control_layout",
           "layout_table"]

#: spin (rad/s) and speed (m/s) that count as 1 in the control envs' observations and rewards
SPIN_SCALE = 20.0
SPEED_SCALE = 3.0


@dataclass(frozen=True)
class ObsField:
    """One entry of a flat observation: its name, bounds and meaning (with units)."""

    name: str
    low: float
    high: float
    doc: str

    def for_target(self, target: str) -> ObsField:
        """This field of a generic layout for a named target (``target_x`` -> ``rod_x``)."""
        name = self.name.replace("target", target, 1)
        return replace(self, name=name, doc=self.doc.format(target=target))


def layout_table(layout: tuple[ObsField, ...]) -> str:
    """The observation layout as a docstring table (so the docs cannot drift from the code)."""
    rows = ["    | index | name | low | high | meaning |", "    |---|---|---|---|---|"]
    for i, f in enumerate(layout):
        rows.append(f"    | {i} | {f.name} | {f.low:g} | {f.high:g} | {f.doc} |")
    return "\n".join(rows)


#: the control envs' observation, for a target called ``target`` (the rod or the puck)
CONTROL_LAYOUT = (
    ObsField("mallet_x", -1.0, 1.0, "mallet x / table half width"),
    ObsField("mallet_y", -1.0, 1.0, "mallet y / table half height"),
    ObsField("mallet_vx", -5.0, 5.0, "mallet vx / max_speed"),
    ObsField("mallet_vy", -5.0, 5.0, "mallet vy / max_speed"),
    ObsField("target_x", -1.0, 1.0, "{target} x / table half width"),
    ObsField("target_y", -1.0, 1.0, "{target} y / table half height"),
    ObsField("target_cos", -1.0, 1.0, "cos({target} angle)"),
    ObsField("target_sin", -1.0, 1.0, "sin({target} angle)"),
    ObsField("target_vx", -10.0, 10.0, f"{{target}} vx / {SPEED_SCALE} m/s"),
    ObsField("target_vy", -10.0, 10.0, f"{{target}} vy / {SPEED_SCALE} m/s"),
    ObsField("target_spin", -10.0, 10.0, f"{{target}} spin / {SPIN_SCALE} rad/s (CCW > 0)"),
)


def control_layout(target: str) -> tuple[ObsField, ...]:
    """:data:`CONTROL_LAYOUT` for a target body named ``target``."""
    return tuple(f.for_target(target) for f in CONTROL_LAYOUT)
