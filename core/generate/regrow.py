"""What a generated tree keeps to be grown again exactly (Place Cut): its species, its envelope, its
growth settings and its wind recording, as one JSON-able document; :func:`inputs_from_doc` gives
them back, and :func:`.growth.grow_tree` with them (and the same seed) grows the same tree."""
from __future__ import annotations

import dataclasses
import json

from ..envelope import Envelope
from .envelopes import envelope_doc, envelope_from_doc
from .growth import GrowParams
from .species import SpeciesModel, dumps_species

FORMAT = "tree_from_video.growth_inputs"


def inputs_doc(model: SpeciesModel, env: Envelope, params: GrowParams, audio: str | None) -> dict:
    """The document of a growth: ``species`` (the species file's JSON), ``envelope``
    (:func:`.envelopes.envelope_doc`), ``params`` (:class:`GrowParams` but its cuts, kept apart),
    ``audio`` (a path or None)."""
    fields = {f.name: getattr(params, f.name) for f in dataclasses.fields(GrowParams) if f.name != "cuts"}
    if fields.get("tree_phase") is not None:
        fields["tree_phase"] = [float(v) for v in fields["tree_phase"]]
    return {"format": FORMAT, "species": json.loads(dumps_species(model)), "envelope": envelope_doc(env),
            "params": fields, "audio": audio}


def inputs_from_doc(doc: dict) -> tuple[SpeciesModel, Envelope, GrowParams, str | None]:
    """``(model, envelope, params, audio)`` of :func:`inputs_doc`'s document."""
    params = dict(doc["params"])
    if params.get("tree_phase") is not None:
        params["tree_phase"] = tuple(params["tree_phase"])
    return (SpeciesModel.from_json(doc["species"], "the tree's kept species"), envelope_from_doc(doc["envelope"]),
            GrowParams(**params), doc.get("audio"))
