"""``ins process``: the configuration (:mod:`~ins.estimation.pipeline.config`,
:mod:`~ins.estimation.pipeline.presets`), the GNSS source
(:mod:`~ins.estimation.pipeline.gnss_source`, tight coupling
:mod:`~ins.estimation.pipeline.tight`), the identification before the run
(:mod:`~ins.estimation.pipeline.identify`), the run
(:mod:`~ins.estimation.pipeline.process`), its trust checks
(:mod:`~ins.estimation.pipeline.trust`), outputs
(:mod:`~ins.estimation.pipeline.outputs`, :mod:`~ins.estimation.pipeline.state_files`,
:mod:`~ins.estimation.pipeline.heading_files`), plots
(:mod:`~ins.estimation.pipeline.plots`), report (:mod:`~ins.estimation.pipeline.report`)
and truth comparison (:mod:`~ins.estimation.pipeline.truth`).

Imports every other subpackage of :mod:`ins.estimation`.
"""
