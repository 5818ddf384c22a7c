"""A stand-in for the ``blender`` executable, built on pip's ``bpy`` module (no Blender binary is installed here).

It reads Blender's command line the way Blender does for what the farm job definitions use, in order:
``-b`` (always background here), ``--factory-startup`` (pip's bpy reads no user preferences anyway),
``--addons MODULE[,MODULE]`` (enabled with ``addon_utils.enable``, as Blender does: extensions come from the
user repository under ``BLENDER_USER_RESOURCES``), ``--python-exit-code N``, ``--python-expr CODE`` (run at
once; ``sys.exit`` inside it ends the process with that status), a ``.blend`` path (opened), and ``--``
(the rest is left to the script in ``sys.argv``).  Anything else is refused, so that a job definition
cannot pass here with arguments a real Blender would not take.
"""
import sys
import traceback


def main(argv) -> int:
    import bpy  # first: it puts Blender's own modules (addon_utils) on the path
    import addon_utils

    sys.argv = ["blender", *argv]
    exit_code = 0
    i = 0
    while i < len(argv):
        argument = argv[i]
        if argument == "--":
            break
        if argument in ("-b", "--background", "--factory-startup"):
            i += 1
        elif argument == "--addons":
            for module in argv[i + 1].split(","):
                if addon_utils.enable(module, default_set=True) is None:
                    print(f"blender_cli: add-on {module} could not be enabled", file=sys.stderr)
                    return 1
            i += 2
        elif argument == "--python-exit-code":
            exit_code = int(argv[i + 1])
            i += 2
        elif argument == "--python-expr":
            try:
                exec(compile(argv[i + 1], "<string>", "exec"), {"__name__": "__main__"})
            except SystemExit as stop:
                return stop.code if isinstance(stop.code, int) else (0 if stop.code is None else 1)
            except Exception:
                traceback.print_exc()
                if exit_code:
                    return exit_code
            i += 2
        elif argument.endswith(".blend"):
            bpy.ops.wm.open_mainfile(filepath=argument)
            i += 1
        else:
            print(f"blender_cli: argument {argument!r} is not emulated", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
