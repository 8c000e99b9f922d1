"""claychain macro: the pellet-powder mixture mock-up (Caulk 2022, Chap. 4) fed by the
pellet permeability table of the upscaling stage.

Entry point: :func:`macro.run.run` (``config, case, table_path, CaseOutputs(result, figure)``),
around the library function :func:`macro.mock_up.mock_up`.
Modules, among others (``__all__`` lists them all): ``laws`` (constitutive laws),
``packing`` (random packing in the cylinder by overlap-energy minimisation), ``field``
(powder heterogeneity), ``mixture`` (systems and exchanges on the Delaunay mesh),
``transport`` (mass update), ``newton`` (local pressure-volume solve), ``model`` (the
coupled step, composed of ``geometry``, ``hydraulics``, ``extrusion``,
``pressure_volume``, ``mechanics`` and ``readings``), ``sensors`` (the wall's pressure
sensors), ``stopping`` (the stop criterion and the progress line), ``figures``,
``ensemble`` (statistics of a case run with several seeds), ``column_permeability``.
"""

import pkgutil

# the public modules as they are on disk, not a list kept by hand
__all__ = sorted(module.name for module in pkgutil.iter_modules(__path__) if not module.name.startswith("_"))
