"""``ins process``: the configuration (:mod:`.config`, :mod:`.presets`), the GNSS source
(:mod:`.gnss_source`, tight coupling :mod:`.tight`), the identification before the run
(:mod:`.identify`), the run (:mod:`.process`), its trust checks (:mod:`.trust`), outputs
(:mod:`.outputs`, :mod:`.state_files`, :mod:`.heading_files`), plots (:mod:`.plots`),
report (:mod:`.report`) and truth comparison (:mod:`.truth`).

Imports every other subpackage of :mod:`ins.estimation`.
"""
