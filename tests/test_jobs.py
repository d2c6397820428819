"""A run as a typed job (issue 34): one ``from_flat`` builds it from the batch options by name for
the command line, a job file, the farm and the API; ``to_flat`` gives the options back (the same
job again, JSON, the same command line); bad options are one line; the API runs it as the batch
does, report and all."""
import argparse
import json
import os

import pytest

from tree_from_video import api, cli
from tree_from_video.core import jobs
from tree_from_video.core.asset.game import ENGINES
from tree_from_video.core.errors import InputError
from tree_from_video.core.farm.report import read_report
from tree_from_video.core.formats import FORMATS

from samples import committed

pytestmark = [pytest.mark.bpy53]


def _flat(argv: list[str]) -> dict:
    return cli.options(cli.build_parser().parse_args(argv))


def test_the_options_are_the_batch_parsers():
    """Every option of a job is a batch option of the same kind, and every batch option that is not
    about how the command runs (--job, --force, --farm…) is a job's."""
    actions = {a.dest: a for a in cli.build_parser()._actions if a.dest != "help"}
    runner = set(cli.BESIDE_JOB) | set(cli.FARM_OPTIONS)
    assert set(jobs.OPTIONS) == set(actions) - runner
    for name, kind in jobs.OPTIONS.items():
        a = actions[name]
        assert (a.nargs == 0) == (kind is bool), name
        if kind is list:
            assert isinstance(a, argparse._AppendAction), name                # repeated: --bark-image A --bark-image B
        elif kind is not bool:
            assert (a.type or str) is kind, name


@pytest.mark.parametrize("argv, kind", [
    (["v.mp4", "--outline", "o.json", "--out", "d", "--gltf", "--bones", "64", "--loop", "8"], jobs.ReconstructJob),
    (["v.mp4", "--outline", "auto", "--out", "d", "--generate", "3", "--engine", "unreal"], jobs.ReconstructJob),
    (["p.jpg", "--outline", "o.json", "--out", "d", "--species", "conifer", "--seconds", "5", "--fbx"], jobs.PhotoJob),
    (["--generate", "4", "--species", "broad", "--out", "d", "--envelope", "heart", "--no-leaves", "--usd"],
     jobs.GenerateJob),
    (["--tree", "t/tree3d.npz", "--out", "d", "--engine", "godot"], jobs.ExportJob),
    (["v.mp4", "--outline", "o.json", "--out", "d", "--gltf", "--bark-image", "a.jpg", "--bark-image", "b.jpg",
      "--moss", "0", "--bark-scale", "30"], jobs.ReconstructJob),
    (["--generate", "2", "--species", "broad", "--out", "d", "--allometry", "--envelope-variation", "0.3",
      "--billboard", "256"], jobs.GenerateJob),
    (["--variations", "5", "--exemplars", "a.png", "b.png", "--exemplars", "c.png", "--seed", "3", "--out", "d"],
     jobs.VariationsJob),
    (["--variations", "2", "--exemplars", "a.jpg", "b.png", "--exemplar-outlines", "a.json", "-", "--out", "d"],
     jobs.VariationsJob),
])
def test_each_kind_from_the_line_and_back(argv, kind):
    job = jobs.from_flat(_flat(argv))
    assert type(job) is kind
    flat = jobs.to_flat(job)
    again = jobs.from_flat(json.loads(json.dumps(flat)))            # a job file holds the same job
    assert again == job
    assert jobs.from_flat(_flat(jobs.to_argv(flat))) == job          # and so does its command line
    assert cli.record(job, argv).settings == jobs.settings_doc(job)
    assert not set(jobs.settings_doc(job)) & set(jobs.PLACES)


def test_what_a_job_holds():
    job = jobs.from_flat(_flat(["v.mp4", "--outline", "o.json", "--out", "d", "--engine", "unreal", "--levels", "5",
                                "--no-leaves", "--generate", "2", "--envelope", "heart"]))
    assert isinstance(job, jobs.ReconstructJob) and job.settings.levels == 5 and job.settings.leaves is None
    unreal = ENGINES["unreal"]
    assert job.outputs.formats == tuple(f.flag for f in FORMATS if f.flag in unreal["formats"])
    assert job.outputs.game.bones == unreal["bones"] and job.outputs.game.loop_s == unreal["loop_s"]
    assert job.generate is not None and job.generate.count == 2 and job.generate.leaf_density == 0.0
    assert job.generate.loop_s == unreal["loop_s"]                    # the preset's loop reaches the grown trees
    photo = jobs.from_flat({"video": "p.png", "outline": "o.json", "out": "d", "seconds": 3, "wind": 2.0})
    assert isinstance(photo, jobs.PhotoJob) and (photo.motion.seconds, photo.motion.wind) == (3, 2.0)


@pytest.mark.parametrize("flat, needle", [
    ({"video": "v.mp4", "outline": "o.json", "out": "d", "colour": "red"}, "unknown key 'colour'"),
    ({"video": "v.mp4", "outline": "o.json", "out": "d", "levels": "6"}, "'levels' in the job is a string"),
    ({"video": "v.mp4", "outline": "o.json", "out": "d", "gltf": 1}, "give true or false"),
    ({"video": "v.mp4", "outline": "o.json", "out": "d", "bones": 0, "gltf": True}, "--bones 0"),
    ({"video": "v.mp4", "outline": "o.json", "out": "d", "loop": 5.0}, "--loop cuts the animation"),
    ({"video": "v.mp4", "outline": "o.json", "out": "d", "viewer": True, "fbx": True}, "--viewer plays tree.glb"),
    ({"video": "v.mp4", "outline": "o.json", "out": "d", "envelope": "heart"}, "only applies with --generate"),
    ({"video": "v.mp4", "out": "d"}, "give the tree's outline"),
    ({"out": "d", "levels": 5}, "no VIDEO given"),
    ({"tree": "t.npz", "out": "d"}, "--tree builds the Blender outputs"),
    ({"video": "v.mp4", "outline": "o.json", "out": "d", "levels": 99}, "levels 99"),
    ({"video": "p.jpg", "outline": "o.json", "out": "d", "seconds": 0}, "--seconds 0"),
    ({"video": "v.mp4", "outline": "o.json", "out": "d", "moss": 2.0}, "add --bark-image"),
    ({"video": "v.mp4", "outline": "o.json", "out": "d", "bark_image": ["a.jpg"], "moss": 3.0}, "--moss 3"),
    ({"video": "v.mp4", "outline": "o.json", "out": "d", "bark_image": "a.jpg"}, "a list of file names"),
])
def test_bad_options_are_one_line(flat, needle):
    with pytest.raises(InputError) as exc:
        jobs.from_flat(flat)
    assert needle in str(exc.value) and "\n" not in str(exc.value)


def test_the_api_runs_a_job_as_the_batch_does(tmp_path):
    video, outline = os.path.join(committed("broad"), "video.mp4"), os.path.join(committed("broad"), "outline.json")
    job = api.job(video=video, outline=outline, out=str(tmp_path / "oak"),
                  frames="0:12", no_video=True, levels=4)
    assert isinstance(job, jobs.ReconstructJob) and job.settings.frames == "0:12"
    report = api.run_job(job)
    assert report["status"] == "ok" and report == read_report(str(tmp_path / "oak"))
    assert report["settings"] == jobs.settings_doc(job) and report["video"]["frames"] == [0, 12]
    assert {"skeleton.npz", "tree3d.npz", "overlay.png"} <= {o["path"] for o in report["outputs"]}
    again = api.run_job(jobs.to_flat(job))                            # done: skipped, its report kept
    assert again["started"] == report["started"]
    with pytest.raises(InputError, match="unknown key 'colour'"):
        api.run_job({**jobs.to_flat(job), "colour": "red"})
    bad = tmp_path / "bad.mp4"
    bad.write_bytes(b"not a video")
    (tmp_path / "bad").mkdir()                                        # as a farm makes it: the refusal is reported
    with pytest.raises(InputError, match="bad.mp4"):
        api.run_job(api.job(video=str(bad), outline=outline, out=str(tmp_path / "bad")))
    assert read_report(str(tmp_path / "bad"))["status"] == "bad_input"
