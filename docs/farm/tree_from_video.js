// Tree from Video: a Flamenco 3 job type (https://flamenco.blender.org/usage/job-types/).
// One task per video, each running the add-on's batch entry in Blender on a worker:
//     {blender} {blenderArgs} --python-exit-code 1 --python BATCH_PY -- VIDEO --outline ... --out OUT_DIR/<stem> [options]
// Install: copy this file into the Manager's `scripts/` folder and restart the Manager.
// Flamenco compiles jobs without reading the farm's disks, so the videos are listed in the job's
// settings (one path per line, as the workers see them); each video's outline is
// <stem>.outline.json beside it unless `outline` names a file or `auto`. Each job folder gets the
// batch's report.json and job.log; a video whose folder holds an `ok` report for the same
// settings and input is skipped by the job itself, so a re-submitted job only redoes what is not done.

const JOB_TYPE = {
    label: "Tree from Video",
    settings: [
        { key: "videos", type: "string", required: true,
          description: "Videos to reconstruct, one path a line (as the workers see them)" },
        { key: "out_dir", type: "string", subtype: "dir_path", required: true, visible: "submission",
          description: "Output folder: each video's files go to <out_dir>/<video name>/" },
        { key: "batch_py", type: "string", subtype: "file_path", required: true, visible: "submission",
          description: "batch.py of the installed Tree from Video extension, as the workers see it" },
        { key: "outline", type: "string", default: "beside", visible: "submission",
          description: "'beside': <video name>.outline.json next to each video; 'auto'; or one outline file for all" },
        { key: "engine", type: "string", default: "", choices: ["", "unreal", "unity", "godot", "web"], visible: "submission",
          description: "A game engine's preset (formats, bones, LODs, loop); empty: none" },
        { key: "bones", type: "int32", default: 0, propargs: {min: 0, max: 1024}, visible: "submission",
          description: "A game rig of at most this many bones (0: every bone)" },
        { key: "loop", type: "float", default: 0, visible: "submission",
          description: "A seamless loop of about this many seconds (0: the whole clip)" },
        { key: "fbx", type: "bool", default: false, visible: "submission", description: "Write tree.fbx" },
        { key: "gltf", type: "bool", default: true, visible: "submission", description: "Write tree.glb" },
        { key: "blend", type: "bool", default: false, visible: "submission", description: "Write tree.blend" },
        { key: "preview", type: "bool", default: true, visible: "submission", description: "Write preview.png" },
        { key: "extra", type: "string", default: "", visible: "submission",
          description: "More batch options, space separated (e.g. --frames 0:240 --no-video)" },
    ]
};

function compileJob(job) {
    const settings = job.settings;
    const videos = `${settings.videos}`.split(/\r?\n/).map((s) => s.trim()).filter((s) => s && !s.startsWith("#"));
    if (videos.length == 0) {
        throw "Tree from Video: no video listed in the job's 'videos' setting";
    }
    const names = uniqueNames(videos.map((v) => path.stem(v)));
    for (let i = 0; i < videos.length; i++) {
        job.addTask(videoTask(settings, videos[i], names[i]));
    }
}

// The names made unique in order: a repeated "clip" becomes "clip-2", "clip-3", ... (as the
// batch's own farm does, so both find the same folders).
function uniqueNames(stems) {
    const seen = new Set();
    return stems.map((s) => {
        let name = s, k = 1;
        while (seen.has(name)) {
            k += 1;
            name = `${s}-${k}`;
        }
        seen.add(name);
        return name;
    });
}

function outlineFor(settings, video) {
    const o = `${settings.outline || "beside"}`;
    if (o == "beside") {
        return path.join(path.dirname(video), `${path.stem(video)}.outline.json`);
    }
    return o;
}

function videoTask(settings, video, name) {
    const args = ["--python-exit-code", "1", "--python", settings.batch_py, "--",
                  video, "--outline", outlineFor(settings, video), "--out", path.join(settings.out_dir, name)];
    if (settings.engine) args.push("--engine", settings.engine);
    if (settings.bones > 0) args.push("--bones", `${settings.bones}`);
    if (settings.loop > 0) args.push("--loop", `${settings.loop}`);
    for (const flag of ["fbx", "gltf", "blend", "preview"]) {
        if (settings[flag]) args.push(`--${flag}`);
    }
    if (settings.extra) {
        for (const a of `${settings.extra}`.split(/\s+/)) {
            if (a) args.push(a);
        }
    }
    const task = author.Task(`tree-${name}`, "blender");
    task.addCommand(author.Command("blender-render", {
        exe: "{blender}",
        exeArgs: "{blenderArgs}",
        argsBefore: [],
        blendfile: "",
        args: args,
    }));
    return task;
}
