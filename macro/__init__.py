"""claychain macro: the pellet-powder mixture mock-up (Caulk 2022, Chap. 4) fed by the
pellet permeability table of the upscaling stage.

Entry point: :func:`macro.run.run` (``config, case, table_path, output_path, figure_path``).
Modules: ``laws`` (constitutive laws), ``packing`` (random packing in the cylinder by
overlap-energy minimisation), ``field`` (powder heterogeneity), ``mixture`` (systems and
exchanges on the Delaunay mesh),
``transport`` (explicit mass update, Eq. 4.58), ``newton`` (local pressure-volume solve),
``model`` (the coupled step and the wall readings), ``sensors`` (the wall's pressure
sensors), ``stopping`` (the stop criterion and the progress line), ``figures``,
``ensemble`` (statistics of a case run with several seeds), ``column_permeability``.
"""

__all__ = [
    "column_permeability", "ensemble", "field", "figures", "laws", "mixture", "model", "newton",
    "packing", "run", "sensors", "stopping", "transport",
]
