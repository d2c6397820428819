"""Runs as records a farm can trust (issue 34): every batch job leaves ``report.json`` (status,
settings, input identity, stage seconds, counts, warnings, outputs, versions, peak memory) and
``job.log`` (:mod:`.report`), and a re-run of a finished job is skipped (:mod:`.identity`: the
input's content hash and the settings' hash). Pure Python: no stage is imported here."""
