"""Snakemake glue: stack the convergence study's micro cases over their number of points."""

import logging
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
import _logging  # noqa: E402

from micro.figures import convergence_figure  # noqa: E402
from micro.studies import convergence_dataset  # noqa: E402
from shared.io import read_dataset, write_dataset  # noqa: E402

sm = snakemake  # noqa: F821
_logging.setup(sm.log[0])
cases = {Path(p).stem: read_dataset(p) for p in sm.input}
ds = convergence_dataset(cases)
logging.getLogger("micro").info("convergence: n_points %s from cases %s", ds["n_points"].values.tolist(),
                                 ds.attrs["cases"])
write_dataset(ds, sm.output.result, stage="studies", title="micro convergence study (n_points)",
              config={"micro": {"studies": {"convergence": list(sm.params.cases)}}},
              inputs=list(sm.input), rule=sm.rule,
              references="Caulk (2022), PhD thesis, Univ. Grenoble Alpes, Sec. 3.5.8")
convergence_figure(ds, sm.output.figure)
