// SPDX-License-Identifier: GPL-3.0-or-later
//
// Flamenco 3 job type: Scratch Iridescence frames, each split by samples over `chunks` tasks and merged
// bit for bit (docs/rendering.md, "Render farms and clusters").
//
// Per frame:   export-N                         Blender opens the .blend and exports frame N as a Mitsuba
//                                               folder on the shared storage (the job's work folder);
//              chunk-N-K (K = 1..chunks)        depends on export-N: renders part K of the frame's fixed
//                                               sample schedule (`render --chunk K/chunks`) into an EXR part;
//              merge-N                          depends on every chunk-N-K: adds the parts' exact sums into
//                                               frame_NNNN.exr, bit for bit the one-machine render.
//
// Workers start Blender with --factory-startup, so the extension is enabled explicitly on every command
// line (--addons bl_ext.<repository>.scratch_iridescence); its bundled Mitsuba renders, no PYTHONPATH needed.
// Chunk and merge tasks run the bridge's command line from --python-expr, which exits Blender before the
// .blend named after it would load (Flamenco's blender-render command always names one).
//
// Install: copy this file into the `scripts/` folder beside flamenco-manager and restart the Manager.

const JOB_TYPE = {
    label: "Scratch Iridescence Render",
    description: "Frames rendered by the Scratch Iridescence engine, each split by samples over several workers",
    settings: [
        { key: "blender_cmd", type: "string", default: "{blender}", visible: false },
        { key: "blender_args", type: "string", default: "{blenderargs}", visible: false },
        { key: "filepath", type: "string", subtype: "file_path", required: true,
          description: "The .blend file (on the shared storage)" },
        { key: "frames", type: "string", required: true,
          eval: "f'{C.scene.frame_start}-{C.scene.frame_end}'",
          description: "Frames to render, e.g. 1-240 or 1,5,10-12" },
        { key: "chunks", type: "int32", default: 4, propargs: { min: 1, max: 1024 },
          description: "Render tasks per frame: each renders 1/chunks of the frame's samples" },
        { key: "samples", type: "int32", default: 0, propargs: { min: 0 },
          description: "Samples per pixel; 0 renders with the scene's own setting" },
        { key: "variant", type: "string", default: "llvm_ad_spectral",
          choices: ["llvm_ad_spectral", "cuda_ad_spectral"],
          description: "All tasks of a frame must use one variant: CPU and GPU chunks differ in their last bits" },
        { key: "render_output_root", type: "string", subtype: "dir_path", required: true,
          description: "Folder for frame_NNNN.exr; the exported scenes and parts go into its 'work' folder" },
        { key: "extension_module", type: "string", default: "bl_ext.user_default.scratch_iridescence",
          description: "The installed extension's module: bl_ext.<repository>.scratch_iridescence" },
    ]
};

function compileJob(job) {
    const settings = job.settings;
    const chunks = settings.chunks;
    if (!(chunks >= 1)) {
        throw `chunks must be at least 1, got ${chunks}`;
    }
    const entry = `import ${settings.extension_module}.addon.render.frames as frames; frames.main()`;
    const blender = (pythonArgs) => ["-b", "--factory-startup", "--addons", settings.extension_module,
                                     "--python-exit-code", "1", ...pythonArgs];
    const command = (argsBefore, args) => author.Command("blender-render", {
        exe: settings.blender_cmd,
        exeArgs: settings.blender_args,
        argsBefore: argsBefore,
        blendfile: settings.filepath,
        args: args,
    });
    const work = path.join(settings.render_output_root, "work");
    const renderOptions = ["--variant", settings.variant];
    if (settings.samples > 0) {
        renderOptions.push("--spp", String(settings.samples));
    }

    for (const frame of frameChunker(settings.frames, 1)) {
        const number = String(frame).padStart(4, "0");
        const scene = path.join(work, `scene_${number}`);

        // The .blend loads first (it precedes --python-expr), then the frame is exported from it.
        const exportTask = author.Task(`export-${frame}`, "blender");
        exportTask.addCommand(command(blender([]),
            ["--python-expr", entry, "--", "export", String(frame), "-o", scene]));
        job.addTask(exportTask);

        const parts = [];
        const chunkTasks = [];
        for (let part = 1; part <= chunks; part++) {
            const output = path.join(work, `part_${number}_${part}of${chunks}.exr`);
            const task = author.Task(`chunk-${frame}-${part}`, "blender");
            task.addCommand(command(blender(["--python-expr", entry]),
                ["--", "render", scene, "-o", output, "--chunk", `${part}/${chunks}`, ...renderOptions]));
            task.addDependency(exportTask);
            job.addTask(task);
            parts.push(output);
            chunkTasks.push(task);
        }

        const mergeTask = author.Task(`merge-${frame}`, "blender");
        mergeTask.addCommand(command(blender(["--python-expr", entry]),
            ["--", "merge", ...parts, "-o", path.join(settings.render_output_root, `frame_${number}.exr`)]));
        for (const task of chunkTasks) {
            mergeTask.addDependency(task);
        }
        job.addTask(mergeTask);
    }
}
