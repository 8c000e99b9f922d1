"""Snakemake glue: mean and std of the scale study's realizations per domain fraction."""

import logging
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
import _logging  # noqa: E402

from micro.config import Realization  # noqa: E402
from micro.figures import scale_figure  # noqa: E402
from micro.studies import scale_dataset  # noqa: E402
from shared.io import read_dataset, write_dataset  # noqa: E402

sm = snakemake  # noqa: F821
_logging.setup(sm.log[0])
layout = sm.params.layout
realizations = [Realization(**{**r, "offset": tuple(r["offset"])}) for r in layout["realizations"]]
outputs = {Path(p).stem: p for p in sm.input.realizations}
ds = scale_dataset(
    (layout["reference"], read_dataset(sm.input.reference)),
    layout["reference_edge_m"],
    [(r, read_dataset(outputs[r.name])) for r in realizations],
)
logging.getLogger("micro").info("scale: domain fractions %s, realizations %s",
                                 ds["domain_fraction"].values.tolist(), ds["n_realizations"].values.tolist())
write_dataset(ds, sm.output.result, stage="studies", title="micro scale study (domain fraction)",
              config={"micro": {"studies": {"scale": dict(layout)}}},
              inputs=[sm.input.reference, *sm.input.realizations], rule=sm.rule,
              references="Caulk (2022), PhD thesis, Univ. Grenoble Alpes, Sec. 3.5.9")
scale_figure(ds, sm.output.figure)
