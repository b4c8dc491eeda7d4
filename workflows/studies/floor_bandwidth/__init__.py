"""The linear floor against the machine: the bytes a V-cycle and a PCG step of the floor
must move, over their time, against the STREAM triad bandwidth of one core."""
from workflows.studies._base import Study, scenes_of

RULE = "floor_bandwidth_study"


def floor_bandwidth_args(config: dict, scene: str) -> str:
    """A scene's settings of the floor_bandwidth study as arguments of
    ``workflows/studies/floor_bandwidth/run.py``."""
    fb = config["floor_bandwidth"]
    levels = " ".join(map(str, scenes_of(config, "floor_bandwidth")[scene]))
    return (f"--levels {levels} --repeats {fb['repeats']} --cg-steps {fb['cg_steps']} "
            f"--stream-mb {fb['stream_mb']}")


STUDY = Study(
    name="floor_bandwidth",
    summary="the linear floor against the machine: bytes a geometric-multigrid V-cycle "
            "and a PCG step must move (matrix values, index arrays, vectors) over their "
            "measured time, against one core's STREAM triad bandwidth, and what float32 "
            "values or a matrix-free operator could gain at most",
    thesis="Example 8.1 (O(N)): the floor the contact solvers are measured against, "
           "placed against the memory bandwidth (the suite's addition)",
    order=55,
    scripts={"floor_bandwidth": "workflows.studies.floor_bandwidth.run"},
    paths={
        "fb_runs": "results/{scene}/floor_bandwidth_runs.csv",
        "fb_table": "results/{scene}/floor_bandwidth.csv",
        "fb_figure": "results/{scene}/floor_bandwidth.png",
    },
    outputs=("fb_table", "fb_figure"),
    heavy_rules=(RULE,),
    runs_alone=(RULE,),
    inline={"fb_table": ("level", "N", "vcycle_mb", "t_vcycle_ms", "vcycle_gbs",
                         "vcycle_of_triad", "cg_step_gbs", "cg_step_of_triad",
                         "index_share", "float32_gain", "matrix_free_gain")},
)
