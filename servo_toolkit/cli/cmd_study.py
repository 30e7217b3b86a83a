"""``servo-toolkit study SCENE NAME``: run one ``[studies.NAME]`` of any kind;
``servo-toolkit study SCENE`` lists the scene's studies and the registered kinds.

The study runs through its kind's descriptor (:mod:`servo_toolkit.scene.study_kind`): the
built-in kinds and those an installed package registers (entry-point group
``servo_toolkit.studies``) alike. The result's table is printed with its units (its own
``table()``, else the scalars of its ``to_dict()``); ``--json FILE`` writes ``to_dict()``
atomically (checked before the run: never over the scene or another input).
"""

from __future__ import annotations

from .common import add_scene, load_scene


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("study", help="run one [studies.NAME] of any kind (built in or from an installed package)")
    add_scene(p)
    p.add_argument("name", metavar="NAME", nargs="?",
                   help="the study: a [studies.NAME] of the scene (or a built-in study of a seed-mechanism scene); "
                        "without it, list the scene's studies (kind, what it computes, the commands that run it) "
                        "and the registered kinds")
    p.add_argument("--json", metavar="FILE", help="write the result's to_dict() as JSON to FILE")
    p.set_defaults(run=run)


def run(args) -> int:
    """Run the command."""
    import sys

    from ..core.files import check_output_file, write_text
    from ..core.json_text import to_json
    from ..display.result_table import scalar_rows, text_table
    from ..studies.run import run_study, study_of
    scene = load_scene(args.scene)
    if args.name is None:
        if args.json is not None:
            from ..errors import SceneError
            raise SceneError("--json", "writes a study's result: name the study (servo-toolkit study SCENE NAME)")
        sys.stdout.write(study_list(scene))
        return 0
    study = study_of(scene, args.name)
    if args.json is not None:
        check_output_file(args.json, "--json", suffixes=(".json",), inputs=(args.scene, *scene.input_files))
    result = run_study(scene, args.name)
    if args.json is not None:
        write_text(args.json, to_json(result.to_dict()) + "\n", key="--json")
    kind = getattr(study, "kind", args.name)
    text = result.table() if hasattr(result, "table") else text_table(scalar_rows(result.to_dict()))
    sys.stdout.write(f"Study {args.name} ({kind}) of {scene.name}\n{text.rstrip()}\n")
    return 0


def study_list(scene) -> str:
    """The text ``servo-toolkit study SCENE`` prints: one row per study of ``scene`` (its file's,
    then the built-in mechanism studies) with its kind, what that kind computes and the
    commands that run it, then the registered kinds."""
    from ..display.result_table import text_table
    from ..scene.study_kind import study_kinds
    from ..studies.run import study_names
    kinds = study_kinds()
    rows = []
    for name in study_names(scene):
        study = scene.studies.get(name)
        if study is None:  # a roller-screw scene's own studies, run by its seed-mechanism model
            rows.append((name, "built in", "the roller screw's seed-mechanism study", "servo-toolkit study"))
            continue
        kind = kinds[study.kind]
        rows.append((name, kind.name, kind.summary, kind.commands))
    table = text_table(rows, head=("study", "kind", "what it computes", "run with")) if rows else \
        "(no [studies.NAME] table; the commands run their default studies)"
    listed = ", ".join(sorted(kinds))
    return (f"Studies of {scene.name}\n{table}\nRun one: servo-toolkit study {scene.source or 'SCENE'} NAME. "
            f"Registered kinds: {listed}.\n")
