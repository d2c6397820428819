// Runs a Flamenco 3 job compiler under node against the author API Flamenco documents
// (https://flamenco.blender.org/development/job-types/: author.Task(name, type),
// author.Command(name, parameters), task.addCommand(cmd), job.addTask(task); the globals `path`
// and `print`), and prints the job's tasks as JSON.
//     node tests/flamenco_author.mjs COMPILER.js SETTINGS.json
import fs from "node:fs";
import nodePath from "node:path";
import vm from "node:vm";

const [compilerFile, settingsFile] = process.argv.slice(2);
const tasks = [];
const author = {
    Task(name, type) {
        if (typeof name !== "string" || typeof type !== "string") throw new Error("author.Task(name, type)");
        const task = { name, type, commands: [], addCommand(cmd) { this.commands.push(cmd); },
                       addDependency(other) { (this.deps ||= []).push(other.name); } };
        return task;
    },
    Command(name, parameters) {
        if (typeof name !== "string" || typeof parameters !== "object") throw new Error("author.Command(name, parameters)");
        return { name, parameters };
    },
};
const path = {
    join: (...p) => nodePath.posix.join(...p),
    basename: (p) => nodePath.posix.basename(p),
    dirname: (p) => nodePath.posix.dirname(p),
    stem: (p) => nodePath.posix.basename(p, nodePath.posix.extname(p)),
};
const job = { name: "trees", created: new Date(), settings: JSON.parse(fs.readFileSync(settingsFile, "utf8")),
              addTask(task) { tasks.push(task); } };
const context = vm.createContext({ author, path, print: (...a) => console.error(...a) });
vm.runInContext(fs.readFileSync(compilerFile, "utf8"), context, { filename: compilerFile });
vm.runInContext("this.__JOB_TYPE = JOB_TYPE; this.__compile = compileJob;", context);
try {
    context.__compile(job);
} catch (e) {
    console.log(JSON.stringify({ error: String(e) }));
    process.exit(0);
}
console.log(JSON.stringify({
    settings: context.__JOB_TYPE.settings.map((s) => s.key),
    tasks: tasks.map((t) => ({ name: t.name, type: t.type,
                               commands: t.commands.map((c) => ({ name: c.name, parameters: c.parameters })) })),
}));
