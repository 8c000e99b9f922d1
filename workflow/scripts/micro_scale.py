"""Snakemake glue: mean and std of the scale study's realizations per domain fraction."""

import logging
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
import _logging  # noqa: E402

from micro.figures import scale_figure  # noqa: E402
from micro.studies import scale_dataset  # noqa: E402
from shared.io import read_dataset, write_dataset  # noqa: E402

sm = snakemake  # noqa: F821
_logging.setup(sm.log[0])
cases = {Path(p).stem: read_dataset(p) for p in sm.input}
scale = dict(sm.params.scale)
ds = scale_dataset(cases, dict(sm.params.edge_lengths), scale["reference"])
logging.getLogger("micro").info("scale: domain fractions %s, realizations %s",
                                 ds["domain_fraction"].values.tolist(), ds["n_realizations"].values.tolist())
write_dataset(ds, sm.output.result, stage="studies", title="micro scale study (domain fraction)",
              config={"micro": {"studies": {"scale": scale},
                                "edge_lengths_m": dict(sm.params.edge_lengths)}},
              inputs=list(sm.input), rule=sm.rule,
              references="Caulk (2022), PhD thesis, Univ. Grenoble Alpes, Sec. 3.5.9")
scale_figure(ds, sm.output.figure)
