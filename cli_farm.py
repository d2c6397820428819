"""``batch.py --farm FOLDER|LIST.txt|JOBS.json --out DIR [--scheduler ADDRESS] [--workers N]
[--job-timeout S] [--blender PATH] [the usual options]``: a job per video, each an ordinary batch
job (its own ``DIR/<stem>/report.json``) run in a subprocess on a Dask worker
(:mod:`.core.farm.runner`). Done jobs are skipped before any worker starts; ``DIR/farm.json``
lists every job's outcome. Exit 0 when every job is ok or skipped, 1 when one failed, 2 when the
farm's own arguments are bad."""
from __future__ import annotations

import os
import sys
import time
from types import SimpleNamespace

from .core.errors import InputError
from .core.farm import identity, inputs, runner
from .core.farm.report import read_report
from .core.jobs import from_flat
from .core.jobs import to_argv as options_argv

#: the farm's own options: not handed to its jobs
FARM_ONLY = ("video", "outline", "tree", "out", "dry_run", "job", "quiet", "record", "begun",
             "farm", "scheduler", "workers", "job_timeout", "blender")
BATCH = os.path.join(os.path.dirname(os.path.abspath(__file__)), "batch.py")


def job_options(args, cli: SimpleNamespace) -> list[str]:
    """The usual options given on the farm's line (those that differ from the defaults), as a
    command line every job gets."""
    parser = cli.build_parser()
    defaults = vars(parser.parse_args([]))
    argv: list[str] = []
    for a in parser._actions:
        if a.dest in FARM_ONLY or a.dest == "help" or not a.option_strings:
            continue
        value = getattr(args, a.dest)
        if value == defaults[a.dest]:
            continue
        argv += [a.option_strings[0]] if a.nargs == 0 else [a.option_strings[0], str(value)]
    return argv


def _check(args) -> None:
    if args.video is not None or args.job or args.tree:
        raise InputError("--farm takes its videos from FOLDER|LIST.txt|JOBS.json; drop the VIDEO / --job / --tree")
    if not args.out:
        raise InputError("--farm needs --out DIR (each job writes DIR/<stem>/)")
    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers {args.workers}: give at least 1")
    if args.job_timeout < 0:
        raise InputError(f"--job-timeout {args.job_timeout:g}: give seconds ≥ 0 (0: no limit)")
    if args.blender and not os.path.isfile(args.blender):
        raise InputError(f"--blender '{args.blender}' does not exist; give the path of a Blender executable")
    if os.path.exists(args.out) and not os.path.isdir(args.out):
        raise InputError(f"--out '{args.out}' is a file; give a folder")


def _decision(job: inputs.FarmJob, force: bool, cli: SimpleNamespace) -> identity.Decision:
    """Run, redo or skip ``job``, from the report its folder holds (the job's own rule)."""
    prior = read_report(job.out) if os.path.isdir(job.out) else None
    if prior is None:
        return identity.Decision("run", "no report yet")
    try:
        rec = cli.record(from_flat(cli.options(cli.build_parser().parse_args(job.argv))), job.argv)
    except (InputError, SystemExit):
        return identity.Decision("run", "its options are refused: the job reports why")
    return identity.decide(prior, rec.settings_sha256, rec.input, force)


def main(args, argv: list[str], cli: SimpleNamespace) -> int:
    """The farm command (module docstring); ``args`` parsed by ``cli.build_parser``; ``cli`` the
    batch's ``build_parser``, ``options`` and ``record`` (handed in: the batch imports the farm, not
    the other way)."""
    _check(args)
    options = job_options(args, cli)
    entries = inputs.read_source(args.farm)

    def to_argv(entry: dict) -> list[str]:
        own = options_argv(entry, args.farm)
        head = own[:1] if entry.get("video") is not None else []
        return head + options + own[len(head):]

    jobs = inputs.plan_jobs(entries, args.out, args.outline, to_argv)
    decisions = [_decision(j, args.force, cli) for j in jobs]
    if args.dry_run:
        for j, d in zip(jobs, decisions):
            print(f"{d.action}: {j.name}: {d.why}")
        return 0
    workers = args.workers or os.cpu_count() or 1
    os.makedirs(args.out, exist_ok=True)
    todo = [i for i, d in enumerate(decisions) if d.action != "skip"]
    outcomes = [runner.JobOutcome(j, "skipped", message=d.why) if d.action == "skip" else None
                for j, d in zip(jobs, decisions)]
    for i in todo:
        os.makedirs(jobs[i].out, exist_ok=True)            # so a job refused at once still leaves its report
        if decisions[i].action == "redo":
            jobs[i].argv = jobs[i].argv + ["--force"]
    run = [jobs[i] for i in todo]
    if args.blender:
        commands = [[args.blender, "-b", "--factory-startup", "--python", BATCH, "--", *j.argv] for j in run]
    else:
        commands = [[sys.executable, BATCH, *j.argv] for j in run]
    sys.stderr.write(f"[farm] {len(jobs)} job(s): {len(run)} to run, {len(jobs) - len(run)} done already"
                     + (f", on {args.scheduler}" if args.scheduler else f", {workers} local worker(s)") + "\n")
    t0 = time.monotonic()
    client = cluster = None
    stopped = False
    try:
        if run:
            client, cluster = runner.open_client(args.scheduler, workers)
            done, stopped = runner.run_farm(client, run, commands, args.job_timeout,
                                            lambda m: sys.stderr.write(m + "\n"))
            for i, o in zip(todo, done):
                outcomes[i] = o
    except KeyboardInterrupt:                      # while the cluster started
        stopped = True
        for i in todo:
            outcomes[i] = runner.JobOutcome(jobs[i], "cancelled", message="the farm was stopped")
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
    final = [o for o in outcomes if o is not None]
    path = runner.write_farm(args.out, args.farm, final, time.monotonic() - t0, args.scheduler, workers)
    if stopped:
        sys.stderr.write(f"cancelled: the farm was stopped; finished jobs keep their reports -> {path}\n")
        return 1
    failed = [o for o in final if o.status not in ("ok", "skipped")]
    sys.stderr.write(f"farm: {len(final) - len(failed)} of {len(final)} ok or done already"
                     + (f", {len(failed)} failed ({', '.join(o.job.name for o in failed)})" if failed else "")
                     + f", {time.monotonic() - t0:.0f} s -> {path}\n")
    return 1 if failed else 0
