"""The report a batch job leaves (core/farm/report.py), read and checked against its published
schema, docs/report.schema.json (JSON Schema 2020-12, with the jsonschema package)."""
import json
import os

from samples import ROOT

SCHEMA_PATH = os.path.join(ROOT, "docs", "report.schema.json")


def check_report(folder) -> dict:
    """``folder/report.json``, valid against the schema, and its ``job.log`` beside it."""
    with open(os.path.join(folder, "report.json"), encoding="utf-8") as fh:
        doc = json.load(fh)
    check_report_doc(doc)
    assert os.path.isfile(os.path.join(folder, "job.log"))
    return doc


def check_report_doc(doc: dict) -> None:
    """A report's JSON, valid against the schema."""
    with open(SCHEMA_PATH, encoding="utf-8") as fh:
        schema = json.load(fh)
    try:
        import jsonschema
    except ImportError:              # Blender's own Python has no jsonschema: the schema's top level by hand
        assert set(doc) == set(schema["required"]) == set(schema["properties"]), sorted(doc)
        props = schema["properties"]
        assert doc["status"] in props["status"]["enum"] and doc["schema"] == props["schema"]["const"]
        assert all(set(o) == {"path", "bytes"} for o in doc["outputs"])
    else:
        jsonschema.Draft202012Validator(schema).validate(doc)
