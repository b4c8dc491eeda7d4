"""The roll stack of a four-high mill (thesis Sect. 9.3, Figs. 9.10-9.16)."""
from workflows.studies._base import ConfigError, Study, ThesisItem, scenes_of

PATHS = {
    # both strip forces at one level, profiles, fields, solvers
    "roll_runs": "results/{scene}/roll_stack_runs.csv",
    "roll_profiles": "results/{scene}/roll_stack_profiles.csv",
    "roll_contact": "results/{scene}/roll_stack_contact.csv",
    "roll_solver_runs": "results/{scene}/roll_stack_solvers.csv",
    "roll_fields": "results/{scene}/roll_stack_F{force}MN.vtu",
    "roll_table": "results/{scene}/roll_stack_table.csv",
    "roll_claims": "results/{scene}/roll_stack_claims.csv",
    "roll_solver_table": "results/{scene}/roll_stack_solver_table.csv",
    "roll_pressure": "results/{scene}/roll_stack_pressure.png",
    "roll_mesh": "results/{scene}/roll_stack_mesh.png",
    "roll_stress": "results/{scene}/roll_stack_von_mises.png",
    "roll_line_load": "results/{scene}/roll_stack_line_load.png",
    "roll_sag": "results/{scene}/roll_stack_sag.png",
    "roll_strip": "results/{scene}/roll_stack_strip_profile.png",
}


def roll_args(config: dict, scene: str) -> str:
    """A scene's settings of the roll_stack study as arguments of
    ``workflows/studies/roll_stack/run.py``."""
    rs = config["roll_stack"]
    (level,) = scenes_of(config, "roll_stack")[scene]
    args = [f"--level {level}", "--forces " + " ".join(f"{f:g}" for f in rs["forces"]),
            "--crowns " + " ".join(f"{c:g}" for c in rs["crowns"]),
            f"--time-limit {rs['time_limit']}"]
    if rs.get("solver_levels"):
        args += ["--solver-levels " + " ".join(map(str, rs["solver_levels"])),
                 "--solvers " + " ".join(rs["solvers"])]
    if rs.get("alg84_levels"):
        args.append("--alg84-levels " + " ".join(map(str, rs["alg84_levels"])))
    if rs.get("alg84_time_limit"):
        args.append(f"--alg84-time-limit {rs['alg84_time_limit']}")
    return " ".join(args)


def roll_fields(config: dict, scene: str) -> list[str]:
    """The VTU files of the roll_stack study (one per strip force, crowned roll)."""
    return [PATHS["roll_fields"].format(scene=scene, force=f"{f / 1e6:g}")
            for f in config["roll_stack"]["forces"]]


def check(config: dict, registry: dict) -> None:
    """Roll-stack scenes, one level each, forces and crowns within
    the problem's ranges, known solvers at valid levels."""
    from problems.spec import ParameterError
    from solvers.interface import solvers

    rs = config.get("roll_stack")
    if not rs:
        return
    for scene, levels in scenes_of(config, "roll_stack").items():
        spec = registry[config["scenes"][scene]["problem"]]
        if spec.name != "roll_stack":
            raise ConfigError(f"config 'roll_stack.scenes.{scene}': problem {spec.name!r} is "
                              "not allowed; allowed: roll_stack")
        if len(levels) != 1:
            raise ConfigError(f"config 'roll_stack.scenes.{scene}': {levels} is not allowed; "
                              "allowed: one level, e.g. [3]")
        params = dict(config["scenes"][scene].get("params") or {})
        for key, name in (("forces", "force"), ("crowns", "crown")):
            for value in rs[key]:
                try:
                    spec.options(**{**params, name: value})
                except ParameterError as err:
                    raise ConfigError(f"config 'roll_stack.{key}': {err}") from None
        lo, hi = spec.levels
        bad = [lv for lv in rs.get("solver_levels", []) if not lo <= lv <= hi]
        if bad:
            raise ConfigError(f"config 'roll_stack.solver_levels': levels {bad} are not "
                              f"allowed; allowed: {lo}..{hi}")
    known = set(solvers()) | {"pdas_kkt"}
    bad = [s for s in rs.get("solvers", []) if s not in known]
    if bad:
        raise ConfigError(f"config 'roll_stack.solvers': {bad} are not allowed; allowed: "
                          f"{', '.join(sorted(known))}")
    if len({f"{f / 1e6:g}" for f in rs["forces"]}) != len(rs["forces"]):
        raise ConfigError("config 'roll_stack.forces': two forces round to the same MN "
                          "(the fields' file names); allowed: distinct values in MN")


STUDY = Study(
    name="roll_stack",
    summary="the roll stack of a four-high mill (crowned work roll floating on a backup "
            "roll, SI units) at both strip forces: equilibrium, Hertz at the barrel "
            "centre, contact line load and half-width along the barrel, sag of axes and "
            "contact lines with and without the crown, strip profile for crowned and "
            "cylindrical work rolls beside the beam model, von Mises cuts, VTU; the "
            "solvers on the scene at coarser levels",
    thesis="Sect. 9.3, Figs. 9.10-9.16",
    order=90,
    scripts={"roll_stack": "workflows.studies.roll_stack.run"},
    paths=PATHS,
    outputs=("roll_table", "roll_claims", "roll_solver_table", "roll_pressure", "roll_mesh",
             "roll_stress", "roll_line_load", "roll_sag", "roll_strip"),
    heavy_rules=("roll_stack_study",),
    runs_alone=("roll_stack_study",),
    thesis_items=(
        ThesisItem("Fig. 9.10", "roll stack: strip pressure along the work roll",
                   "roll_pressure", "roll_stack"),
        ThesisItem("Fig. 9.11", "roll stack: mesh (thesis: 46,611 nodes, 7,089 inequalities)",
                   "roll_mesh", "roll_stack"),
        ThesisItem("Figs. 9.12/9.13", "roll stack: von Mises stress on cuts", "roll_stress",
                   "roll_stack"),
        ThesisItem("Figs. 9.14-9.16", "roll stack: sag along the rolls' lines, 15 and 30 (MN), "
                   "corrected by the crown (Schliff)", "roll_sag", "roll_stack"),
        ThesisItem("Sect. 9.3 (line load)", "roll stack: contact line load and half-width "
                   "along the barrel, Hertz at the barrel centre", "roll_line_load",
                   "roll_stack"),
        ThesisItem("Sect. 9.3 (strip)", "roll stack: strip thickness profile, crowned and "
                   "cylindrical work rolls", "roll_strip", "roll_stack"),
        ThesisItem("Sect. 9.3 (numbers)", "roll stack: FE beside plane-strain Hertz and the "
                   "beam model", "roll_table", "roll_stack"),
    ),
    check=check,
    claims=("roll_claims",),
    inline={"roll_table": ("force_MN", "crown_um", "level", "N", "status", "q0_MN_per_m",
                           "q0_beam_MN_per_m", "b0_mm", "b0_hertz_mm", "p0_nodal_GPa",
                           "p0_hertz_GPa", "cells_across_2b", "sag_work_axis_um",
                           "sag_work_axis_beam_um", "strip_crown_um", "strip_crown_beam_um")},
)
