"""Contacts of swelling pellets: Hertz-Mindlin between points of their own moduli, with
Coulomb friction and the yield of Eq. 4.4 (Thornton's elastic-perfectly plastic
contact), and contacts with a rigid cylinder closed by two plates (frictionless unless
given a wall friction).

The macro model's pellets use these (Caulk 2022, Eqs. 4.1-4.9); the micro model's
bonded points use :func:`shared.dem.contact_forces`. Both share the contact geometry,
the shear update and the scatter of the kernels in :mod:`shared.dem._kernels`.
"""

from __future__ import annotations

from shared.dem._kernels import cylinder_contacts, hertz_yield, yielding_hertz_mindlin

__all__ = ["cylinder_contacts", "hertz_yield", "yielding_hertz_mindlin"]
