"""The effects registry: the pieces of physics a scene can ask for.

A scene lists its effects; the world is assembled from that list once, at construction. An effect
that is not listed is not computed: its code is behind a flag that is fixed when the world is
built, so a step never runs it (``tests/physics/test_effects.py`` shows this by tracing the
pure-Python kernels), and a parameter set for an effect that is not listed is a ``SceneError``.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["EFFECTS", "Effect"]


@dataclass(frozen=True)
class Effect:
    """One piece of physics, its parameters and what it costs."""

    name: str
    summary: str
    parameters: tuple[str, ...]


EFFECTS: dict[str, Effect] = {
    e.name: e
    for e in (
        Effect(
            "rotation",
            "angular state (omega) and the lever-arm terms (r x n)^2 / I of the impulse; "
            "without it bodies translate only (infinite inertia), each keeping its angle.",
            ("bodies[].omega", "bodies[].inertia", "bodies[].pivot"),
        ),
        Effect(
            "walls",
            "four static cushions on the table's edges (inverse mass and inertia 0).",
            ("table.size",),
        ),
        Effect(
            "contact_friction",
            "Coulomb tangential impulse at a contact, applied after the normal impulse, bounded "
            "by mu * j and by what stops the slip (it never reverses it), so it never adds "
            "energy. It is what lets a struck puck pick up spin.",
            ("materials.friction", "materials.pairs[].friction"),
        ),
        Effect(
            "table_friction",
            "Coulomb friction with the cloth: a sliding body decelerates at mu_t g along its "
            "velocity (straight path) until it stops; its spin decelerates at mu_t g / k "
            "(k = sqrt(I/m), the radius of gyration) until it stops. The two are independent "
            "(a documented simplification). Driven bodies are exempt (their force is net).",
            ("table.friction", "table.gravity"),
        ),
    )
}
