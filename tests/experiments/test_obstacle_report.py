"""The obstacle experiment's tables say which field widths cekm's rows ran with."""

from cekm_swarm.experiments.obstacle_report import summary_markdown, table_markdown
from cekm_swarm.experiments.obstacle_stats import summarize


def _doc(**extra) -> dict:
    rows = [{"scenario": "doorway", "controller": c, "seed": 1, "success": True, "collision_free": True,
             "collisions": 0, "min_clearance_m": 0.01, "time_s": 17.0, "checkpoints_reached": 1, "checkpoints": 1}
            for c in ("cekm", "fusion")]
    scenarios = {"doorway": ("cekm", "fusion")}
    return {"seeds": [1], "summary": summarize(rows, scenarios), "runs": rows, **extra}


def test_cekm_rows_name_widths_other_than_the_papers_methods():
    for doc in (_doc(), _doc(fields="tuned")):  # the reproduction (and documents from before --fields)
        assert "| doorway (Fig. 10) | cekm | 1/1" in summary_markdown(doc)
        assert "| doorway | cekm | yes 17 s" in table_markdown(doc)
    learned = _doc(fields="learned")
    assert "| doorway (Fig. 10) | cekm (learned widths) | 1/1" in summary_markdown(learned)
    assert "| doorway | cekm (learned widths) | yes" in table_markdown(learned)
    assert "| doorway (Fig. 10) | fusion | 1/1" in summary_markdown(learned)
