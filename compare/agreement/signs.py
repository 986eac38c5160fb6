r"""What the sign of a jump ``Φ_i,x`` means (SPEC §2, identity 4).

By identity 2, :math:`\partial J/\partial \text{corner}_{i,x} = -\Phi_{i,x}`; and from the
closed form :math:`\Phi = -K^{-1} e` with :math:`e = \text{corner} - \bar s` (one vehicle:
:math:`\Phi_x = -e_x / K`), :math:`\Phi_{i,x} > 0` exactly when the ego, left to itself at the
contact time, would be *ahead* of (at larger ``x`` than) the corner: the constraint pulls it
back.  For a ``front`` corner (the ego merges ahead of the vehicle) being ahead is the safe
side, so ``Φ_x > 0`` means the equality *drags the ego towards the obstacle*, and
``Φ_x < 0`` means it is a real safety constraint (it pushes the ego forward, out of the
safety box).  For a ``rear`` corner (the ego stays behind) the roles swap.
"""

from __future__ import annotations

import numpy as np

from iamp.core.problem import SurroundingVehicle

from .records import SignEntry


def constraint_is_binding_for_safety(vehicle: SurroundingVehicle, phi_x: float) -> bool:
    """True if the longitudinal part of the equality pushes the ego to the safe side."""
    return bool(phi_x < 0) if vehicle.sign_x > 0 else bool(phi_x > 0)


def constraint_role(vehicle: SurroundingVehicle, phi_x: float) -> str:
    """What the equality is, as the end of a sentence ("the equality is …")."""
    return ("a real safety constraint (it pushes the ego to the safe side of the corner)"
            if constraint_is_binding_for_safety(vehicle, phi_x)
            else "not a safety constraint: it drags the ego towards the obstacle")


def jump_meaning(vehicle: SurroundingVehicle, phi_x: float) -> str:
    """One sentence for reports: is the equality a real safety constraint here?"""
    side = "ahead of" if phi_x > 0 else "behind"
    if phi_x == 0:
        return "Φ_x = 0: the corner lies on the unconstrained path; the equality costs nothing longitudinally"
    verdict = constraint_role(vehicle, phi_x)
    return (f"Φ_x {'>' if phi_x > 0 else '<'} 0: without it the ego would be {side} the "
            f"{vehicle.corner.split('-')[0]} corner; the equality is {verdict}")


def sign_entry(vehicle: SurroundingVehicle, phi_x: float) -> SignEntry:
    """One entry of a comparison's ``signs``: ``Φ_x`` (or ``ν_x``), its sign and meaning."""
    return {"vehicle": vehicle.name, "corner": vehicle.corner, "phi_x": float(phi_x),
            "sign": int(np.sign(phi_x)), "binding_for_safety": bool(constraint_is_binding_for_safety(vehicle, phi_x)),
            "meaning": jump_meaning(vehicle, phi_x)}
