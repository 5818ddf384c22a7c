// A small stand-in for Flamenco Manager's job-compiler environment, after its documentation
// (flamenco.blender.org: "Job Types", "List of Commands"): the globals `author` (Task, Command),
// `path`, `frameChunker` and `print`, a `job` with `settings` and `addTask`, and compileJob(job).
// Usage: node flamenco_author.js JOB_TYPE.js SETTINGS.json  ->  the compiled tasks as JSON on stdout.
"use strict";
const fs = require("fs");
const nodePath = require("path");
const vm = require("vm");

class Task {
    constructor(name, type) {
        this.name = name;
        this.type = type;
        this.commands = [];
        this.dependencies = [];
    }
    addCommand(command) { this.commands.push(command); }
    addDependency(task) {
        if (!(task instanceof Task)) throw new Error(`addDependency(${task}): not a task`);
        this.dependencies.push(task);
    }
}

// frameChunker("1-10,15", 4) -> ["1-4", "5-8", "9,10", "15"] style chunks; with 1 each frame alone.
function frameChunker(frames, chunkSize) {
    const list = [];
    for (const item of String(frames).split(",")) {
        const match = item.trim().match(/^(-?\d+)(?:-(-?\d+))?$/);
        if (!match) throw new Error(`invalid frame range ${item}`);
        const first = Number(match[1]), last = match[2] === undefined ? first : Number(match[2]);
        for (let frame = first; frame <= last; frame++) list.push(frame);
    }
    const chunks = [];
    for (let i = 0; i < list.length; i += chunkSize) {
        const chunk = list.slice(i, i + chunkSize);
        chunks.push(chunk.length === 1 ? String(chunk[0]) : `${chunk[0]}-${chunk[chunk.length - 1]}`);
    }
    return chunks;
}

const [script, settingsFile] = process.argv.slice(2);
const tasks = [];
const job = { name: "test job", created: new Date(0), settings: JSON.parse(fs.readFileSync(settingsFile, "utf8")),
              addTask: (task) => tasks.push(task) };
const context = vm.createContext({
    author: { Task: (name, type) => new Task(name, type), Command: (name, parameters) => ({ name, parameters }) },
    path: { join: nodePath.posix.join, dirname: nodePath.posix.dirname, basename: nodePath.posix.basename,
            stem: (p) => nodePath.posix.parse(p).name },
    frameChunker, print: (...args) => console.error(...args), String, Number, Array, JSON,
});
vm.runInContext(fs.readFileSync(script, "utf8") + "\n;this.JOB_TYPE = JOB_TYPE; this.compileJob = compileJob;", context,
                { filename: script });
for (const setting of context.JOB_TYPE.settings) {  // Flamenco fills in defaults before compiling
    if (!(setting.key in job.settings) && "default" in setting) job.settings[setting.key] = setting.default;
    if (setting.required && !(setting.key in job.settings)) throw new Error(`setting ${setting.key} is required`);
}
context.compileJob(job);
console.log(JSON.stringify({
    label: context.JOB_TYPE.label,
    tasks: tasks.map((t) => ({ name: t.name, type: t.type, commands: t.commands,
                               dependencies: t.dependencies.map((d) => d.name) })),
}, null, 1));
