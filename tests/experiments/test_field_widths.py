"""``--fields``: which graph each choice of field widths is, and that navigation's ``cekm``
(the default controller) is the learned one while the paper's reproductions keep the
paper's method, constant widths."""

import pytest

from cekm_swarm.errors import ParameterError
from cekm_swarm.experiments.field_widths import (
    CONSTANT_GRAPH,
    DEFAULT_FIELDS,
    POLICY_PROGRAM,
    REPRODUCTION,
    fields_graph,
    policy_graph,
)
from cekm_swarm.graph.spec import graph_for, load_graph
from cekm_swarm.modules.motor_integration import MotorIntegration
from cekm_swarm.node.graph_check import check_graph

PLAIN = "cekm_swarm.modules.motor_integration"


def _motor(checked) -> str:
    return checked.graph.node("motor").program


def test_navigations_cekm_is_the_learned_policy_and_cekm_tuned_its_constant_twin():
    cekm = load_graph(graph_for("cekm", "navigation")).to_dict()
    tuned = load_graph(graph_for("cekm-tuned", "navigation")).to_dict()
    assert DEFAULT_FIELDS["navigation"] == "learned" and CONSTANT_GRAPH["navigation"] == "cekm-tuned"
    motor = {n["name"]: n["program"] for n in cekm["nodes"]}["motor"]
    assert motor == POLICY_PROGRAM["navigation"]
    # node for node the same graph but the motor's program, and its reading the raw ranges (the movers' detector)
    for n in (*cekm["nodes"], *tuned["nodes"]):
        if n["name"] == "motor":
            n["program"] = "?"
    motor_node = next(n for n in cekm["nodes"] if n["name"] == "motor")
    ranges = [i for i in motor_node["inputs"] if i["port"] == "ranges"]
    assert [i["key"] for i in ranges] == ["sense/range/*"]
    motor_node["inputs"] = [i for i in motor_node["inputs"] if i["port"] != "ranges"]
    assert cekm["nodes"] == tuned["nodes"] and (cekm["controller"], tuned["controller"]) == ("cekm", "cekm-tuned")


def test_each_choice_is_its_graph_with_its_parameters():
    paper, params = fields_graph("paper", "navigation")
    assert paper.graph.controller == "cekm-tuned" and _motor(paper) == PLAIN and params == {"sigma_b_alpha": 0.495}
    tuned, params = fields_graph("tuned", "navigation")
    assert tuned.graph.controller == "cekm-tuned" and params == {}
    learned, params = fields_graph("learned", "navigation", "p.json")
    assert learned.graph.controller == "cekm" and _motor(learned) == POLICY_PROGRAM["navigation"]
    assert params == {"policy": "p.json"} and fields_graph("learned", "navigation")[1] == {}
    # tracking: cekm keeps constant widths, learned swaps its motor
    assert DEFAULT_FIELDS["tracking"] == "tuned" and fields_graph("tuned", "tracking")[0].graph.controller == "cekm"
    track = fields_graph("learned", "tracking")[0]
    assert _motor(track) == POLICY_PROGRAM["tracking"] and "field policy" in track.graph.description
    assert policy_graph("navigation").controller == "cekm"


def test_bad_choices_are_refused_naming_them():
    with pytest.raises(ParameterError, match=r"--fields must be one of \['paper', 'tuned', 'learned'\], got 'wide'"):
        fields_graph("wide", "navigation")
    with pytest.raises(ParameterError, match="a policy file \\(p.json\\) goes with --fields learned, not paper"):
        fields_graph("paper", "navigation", "p.json")
    with pytest.raises(ParameterError, match="task must be one of"):
        fields_graph("tuned", "swimming")


def test_the_reproductions_run_the_papers_method():
    """Section 4.2's table, Fig. 9's sweep: constant widths, the plain motor integration."""
    from cekm_swarm.experiments.concave_config import SweepConfig

    assert REPRODUCTION == "tuned" and SweepConfig().fields == REPRODUCTION
    checked, _ = fields_graph(REPRODUCTION, "navigation")
    assert check_graph(checked.graph).classes["motor"] is MotorIntegration
    with pytest.raises(ParameterError, match="--fields must be one of"):
        SweepConfig(fields="wide")
