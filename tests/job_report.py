"""The report a batch job leaves (core/farm/report.py), read and checked against its published
schema, docs/report.schema.json (JSON Schema 2020-12, with the jsonschema package)."""
import json
import os

from samples import ROOT

SCHEMA_PATH = os.path.join(ROOT, "docs", "report.schema.json")


def check_report(folder) -> dict:
    """``folder/report.json``, valid against the schema, and its ``job.log`` beside it."""
    import jsonschema  # here, not at import: Blender's Python collects these modules without it
    with open(SCHEMA_PATH, encoding="utf-8") as fh:
        schema = json.load(fh)
    with open(os.path.join(folder, "report.json"), encoding="utf-8") as fh:
        doc = json.load(fh)
    jsonschema.Draft202012Validator(schema).validate(doc)
    assert os.path.isfile(os.path.join(folder, "job.log"))
    return doc
