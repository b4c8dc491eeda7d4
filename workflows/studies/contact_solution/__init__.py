"""Each scene solved exactly per level, checked against Hertz (thesis Sects. 9.1, 9.2)."""
from workflows.studies._base import Study, ThesisItem

STUDY = Study(
    name="contact_solution",
    summary="exact contact solution per level of each scene: Hertz check (2D line or 3D "
            "point contact), fields (VTU), von Mises stress and contact pressure figures",
    thesis="Sects. 9.1, 9.2 (Figs. 9.5, 9.9)",
    order=20,
    scripts={"contact_solution": "workflows.studies.contact_solution.run"},
    paths={
        "contact_level": "results/{scene}/contact_L{level}.csv",
        "hertz_level": "results/{scene}/hertz_L{level}.csv",
        "fields_level": "results/{scene}/fields_L{level}.vtu",
        "hertz": "results/{scene}/hertz.csv",
        "fields_figure": "results/{scene}/fields.png",
        "pressure_figure": "results/{scene}/pressure.png",
        "surface_figure": "results/{scene}/contact_surfaces.png",
    },
    outputs=("hertz", "fields_figure", "pressure_figure", "surface_figure"),
    heavy_rules=("contact_level",),
    thesis_items=(
        ThesisItem("Sect. 9.1 (Hertz)", "circle-square against the Hertz line contact", "hertz",
                   "circle_square"),
        ThesisItem("Fig. 9.5", "cube-sphere: von Mises stress", "fields_figure", "cube_sphere"),
        ThesisItem("Sect. 9.2 (Hertz)", "cube-sphere against the Hertz point contact", "hertz",
                   "cube_sphere"),
    ),
    inline={"hertz": ("level", "nodes", "status", "force", "a_hertz", "a_moment", "dev_a_moment",
                      "p0_hertz", "p0_moment", "dev_p0_moment", "a_over_h")},
    derived_claims={"hertz": "report.contact_solution:claims"},
)
