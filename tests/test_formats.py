"""One registry of output formats (core/formats.py, issue 33): the batch's flags and files, the
panel's Format, the File menu entry and api.export's extensions all come from it, and every writer
it names exists."""
import os

import pytest

from tree_from_video import api, cli
from tree_from_video.core import formats
from tree_from_video.core.errors import InputError
from tree_from_video.operators.scene import export, outputs

from trees import addon  # noqa: F401  (autouse fixture: the add-on registered per test)

pytestmark = [pytest.mark.blender]


def test_the_registry_is_consistent():
    keys = [f.key for f in formats.FORMATS]
    flags = [f.flag for f in formats.FORMATS]
    files = [f.file for f in formats.FORMATS]
    exts = [e for f in formats.FORMATS for e in f.extensions]
    assert len(set(keys)) == len(keys) and len(set(flags)) == len(flags) and len(set(files)) == len(files)
    assert len(set(exts)) == len(exts)                       # an extension names one format
    for f in formats.FORMATS:
        assert os.path.splitext(f.file)[1] in f.extensions
        assert f.writer is None or callable(getattr(export, f.writer))
    assert [f.key for f in formats.interchange()] == ["FBX", "GLB", "USD"]
    assert formats.for_path("/x/Oak.GLB").key == "GLB" and formats.for_path("a.usda").key == "USD"
    assert formats.for_path("a.blend") is None and formats.for_path("a.obj") is None


def test_every_front_end_reads_it(addon):
    # the panel's Format: the interchange formats, with the registry's labels
    items = addon.bl_rna.properties["export_format"].enum_items
    assert [(i.identifier, i.name) for i in items] == [(f.key, f.label) for f in formats.interchange()]
    # the batch: one flag per format, its file in --out
    args = cli.build_parser().parse_args(["v.mp4", "--out", "d"] + [f"--{f.flag}" for f in formats.FORMATS])
    wanted = {f.flag: getattr(args, f.flag) for f in formats.FORMATS}
    assert all(wanted.values())
    assert outputs.wanted_files("d", wanted) == [os.path.join("d", f.file) for f in formats.FORMATS]
    # api.export: an unknown extension lists the registry's
    with pytest.raises(InputError) as err:
        api.export([], "/tmp/oak.obj")
    assert ", ".join(formats.interchange_extensions()) in str(err.value)
