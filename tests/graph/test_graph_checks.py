"""A graph file is refused before anything starts, naming the file, the node and the field:
an unknown program, an unknown key, a cycle with no delay, a duplicate name, a parameter a
node does not declare, a port bound wrong, no rate, a bad answer; an output nobody reads
is a warning. The shipped graphs pass every check."""

from __future__ import annotations

import textwrap

import pytest

from cekm_swarm.graph import GraphError, load_graph, shipped_graphs
from cekm_swarm.node.graph_check import check_graph

PROGRAMS = '''
from dataclasses import dataclass
from cekm_swarm.node import In, Node, Out
from cekm_swarm.protocol import Data, ObstacleField, SenseRange, SenseTarget, Share, WheelCommand


class Target(Node):
    inputs = {"reading": In(SenseTarget)}
    outputs = {"y": Out(Data)}

    def step(self, t, inputs):
        return {"y": Data(t, self.ctx.sender, {})}


class Relay(Node):
    inputs = {"x": In(Data)}
    outputs = {"y": Out(Data)}

    @dataclass(frozen=True)
    class Params:
        gain: float = 1.0

    def step(self, t, inputs):
        return {"y": Data(t, self.ctx.sender, {})}


class Source(Node):
    outputs = {"y": Out(Data)}

    def step(self, t, inputs):
        return {"y": Data(t, self.ctx.sender, {})}


class Wheels(Node):
    inputs = {"x": In(Data)}
    outputs = {"command": Out(WheelCommand)}

    def step(self, t, inputs):
        return {"command": WheelCommand(t, self.ctx.sender, 0.0, 0.0, 0)}


class Ranges(Node):
    inputs = {"ranges": In(SenseRange, many=True)}
    outputs = {"y": Out(Data)}

    def step(self, t, inputs):
        return {"y": Data(t, self.ctx.sender, {})}


class OneRange(Node):
    inputs = {"reading": In(SenseRange)}
    outputs = {"y": Out(Data)}

    def step(self, t, inputs):
        return {"y": Data(t, self.ctx.sender, {})}
'''


@pytest.fixture
def write(tmp_path, monkeypatch):
    (tmp_path / "graph_test_programs.py").write_text(PROGRAMS)
    monkeypatch.syspath_prepend(str(tmp_path))

    def make(body: str, name: str = "g.toml") -> str:
        path = tmp_path / name
        path.write_text(textwrap.dedent(body))
        return str(path)

    return make


P = "graph_test_programs"
HEAD = '[graph]\ncontroller = "mine"\ntask = "navigation"\n'
WHEELS = (f'\n[[node]]\nname = "wheels"\nprogram = "{P}:Wheels"\ninputs = {{ x = "mine/y" }}\n'
          'outputs = { command = "cmd/wheels" }\n')
SOURCE = f'\n[[node]]\nname = "source"\nprogram = "{P}:Source"\nevery = 1\noutputs = {{ y = "mine/y" }}\n'


def refused(path: str, *words: str) -> str:
    with pytest.raises(GraphError) as info:
        checked = check_graph(path)
        checked.plan(("r1", "r2"), "navigation")
    text = str(info.value)
    assert text.startswith(path), text
    for w in words:
        assert w in text, text
    return text


def test_a_good_graph_passes_and_an_unread_output_is_a_warning(write):
    path = write(HEAD + SOURCE + WHEELS + f'\n[[node]]\nname = "spare"\nprogram = "{P}:Source"\nevery = 2\n'
                 'outputs = { y = "mine/spare" }\n')
    plan = check_graph(path).plan(("r1", "r2"), "navigation")
    assert [n.name for n in plan.nodes["r1"]] == ["source", "wheels", "spare"]
    assert plan.warnings == [f"{path}: node 'spare'.outputs.y: 'mine/spare' is read by no node (it is only recorded)"]


def test_an_unknown_program_is_refused(write):
    refused(write(HEAD + WHEELS + '\n[[node]]\nname = "source"\nprogram = "no_such_module_here"\nevery = 1\n'
                  'outputs = { y = "mine/y" }\n'), "node 'source'.program", "unknown program 'no_such_module_here'")
    refused(write(HEAD + WHEELS + f'\n[[node]]\nname = "source"\nprogram = "{P}:Nope"\nevery = 1\n'
                  'outputs = { y = "mine/y" }\n'), "node 'source'.program", "no Node class 'Nope'")


def test_an_unknown_key_is_refused(write):
    refused(write(HEAD + SOURCE + f'\n[[node]]\nname = "wheels"\nprogram = "{P}:Wheels"\ninputs = '
                                  f'{{ x = "mine/typo" }}\n'
                  'outputs = { command = "cmd/wheels" }\n'), "node 'wheels'.inputs.x", "unknown key 'mine/typo'")


def test_a_cycle_with_no_delay_is_refused_and_a_delay_breaks_it(write):
    loop = (HEAD + f'\n[[node]]\nname = "a"\nprogram = "{P}:Relay"\ninputs = {{ x = "mine/b" }}\noutputs = '
                   f'{{ y = "mine/a" }}\n'
            f'\n[[node]]\nname = "b"\nprogram = "{P}:Relay"\ninputs = {{ x = "mine/a" }}\noutputs = '
            f'{{ y = "mine/b" }}\n'
            f'\n[[node]]\nname = "wheels"\nprogram = "{P}:Wheels"\ninputs = {{ x = "mine/a" }}\n'
            'outputs = { command = "cmd/wheels" }\n')
    text = refused(write(loop), "form a cycle", "delay = 1")
    assert "a -> b -> a" in text or "b -> a -> b" in text
    ok = loop.replace('inputs = { x = "mine/b" }', 'inputs = { x = { key = "mine/b", delay = 1 } }\nevery = 1')
    plan = check_graph(write(ok, "ok.toml")).plan(("r1",), "navigation")
    assert {n.name: n.period for n in plan.nodes["r1"]} == {"a": 1, "b": 1, "wheels": 1}


def test_a_duplicate_name_is_refused(write):
    with pytest.raises(GraphError, match="node 'source'.name: duplicate node name"):
        load_graph(write(HEAD + SOURCE + SOURCE + WHEELS))


def test_a_parameter_the_node_does_not_declare_is_refused(write):
    refused(write(HEAD + SOURCE + WHEELS.replace('outputs = { command', 'params = { speed = 2 }\noutputs = { command')),
            "node 'wheels'.params", "parameter 'speed' is not declared", "Wheels")
    refused(
        write(
            HEAD + SOURCE + WHEELS + f'\n[[node]]\nname = "r"\nprogram = "{P}:Relay"\ninputs = '
            f'{{ x = "mine/y" }}\n'
            'outputs = { y = "mine/r" }\nparams = { gain = "fast" }\n'
        ),
        "node 'r'.params.gain",
        "expected a number",
    )
    refused(write("[params]\nwidth = 3\n" + HEAD + SOURCE + WHEELS), "[params].width", "no node of the graph declares")


def test_ports_bound_wrong_are_refused(write):
    refused(
        write(HEAD + SOURCE + WHEELS.replace('inputs = { x = "mine/y" }', 'inputs = { x = "mine/y", z = "mine/y" }')),
        "node 'wheels'.inputs.z",
        "no input port 'z'",
    )
    refused(write(HEAD + SOURCE + WHEELS.replace('inputs = { x = "mine/y" }\n', '')),
            "node 'wheels'.inputs", "input port 'x' of its program is not given a key")
    refused(write(HEAD + SOURCE + WHEELS + f'\n[[node]]\nname = "o"\nprogram = "{P}:OneRange"\n'
                  'inputs = { reading = "sense/range/*" }\noutputs = { y = "mine/o" }\n'),
            "node 'o'.inputs.reading", "takes one key")
    refused(write(HEAD + SOURCE + f'\n[[node]]\nname = "wheels"\nprogram = "{P}:Wheels"\n'
                  'inputs = { x = "sense/target" }\noutputs = { command = "cmd/wheels" }\n'),
            "node 'wheels'.inputs.x", "carries sense/target messages, the port of node 'wheels' takes data")


def test_a_misspelled_port_is_named_with_the_programs_ports(write):
    """A typo in a port's name is refused as the name typed (with the close one), not
    as the real port left unbound; the same for an output port."""
    text = refused(write(HEAD + SOURCE + WHEELS.replace('inputs = { x = "mine/y" }', 'inputs = { xx = "mine/y" }')),
                   "node 'wheels'.inputs.xx", "no input port 'xx'", "(its input ports: x)", "did you mean 'x'?")
    assert "not given a key" not in text
    text = refused(write(HEAD + SOURCE + WHEELS.replace("outputs = { command =", "outputs = { comand =")),
                   "node 'wheels'.outputs.comand", "no output port 'comand'", "(its output ports: command)",
                   "did you mean 'command'?")
    assert "not given a key" not in text
    text = refused(write(HEAD + SOURCE + WHEELS.replace('inputs = { x = "mine/y" }', 'inputs = { zebra = "mine/y" }')),
                   "node 'wheels'.inputs.zebra", "no input port 'zebra' (its input ports: x)")
    assert "did you mean" not in text


def test_no_rate_a_bad_answer_and_the_wrong_task_are_refused(write):
    refused(
        write(HEAD + f'\n[[node]]\nname = "source"\nprogram = "{P}:Source"\noutputs = {{ y = "mine/y" }}\n' + WHEELS),
        "node 'source'.every",
        "no rate",
    )
    refused(write(HEAD.replace('task = "navigation"\n', 'task = "navigation"\nanswer = "mine/y"\n') + SOURCE + WHEELS),
            "[graph].answer", "carries data messages")
    refused(write(HEAD + SOURCE.replace("every = 1", "every = 2") + WHEELS), "[graph].answer", "every 2 ticks")
    with pytest.raises(GraphError, match="is for navigation scenarios"):
        check_graph(write(HEAD + SOURCE + WHEELS)).plan(("r1",), "tracking")
    path = write(HEAD.replace("navigation", "any") + f'\n[[node]]\nname = "o"\nprogram = "{P}:Wheels"\n'
                 'inputs = { x = "mine/y" }\noutputs = { command = "cmd/wheels" }\n' + SOURCE
                 + f'\n[[node]]\nname = "t"\nprogram = "{P}:Relay"\ninputs = {{ x = "mine/y" }}\n'
                   'outputs = { y = "mine/t" }\n'
                 + f'\n[[node]]\nname = "u"\nprogram = "{P}:Ranges"\ninputs = {{ ranges = "sense/target" }}\n'
                   'outputs = { y = "mine/u" }\n')
    with pytest.raises(GraphError, match="carries sense/target messages"):
        check_graph(path).plan(("r1",), "navigation")
    reads_target = write(HEAD.replace("navigation", "any") + SOURCE + WHEELS
                         + f'\n[[node]]\nname = "t"\nprogram = "{P}:Target"\ninputs = {{ reading = "sense/target" }}\n'
                           'outputs = { y = "mine/t" }\n', "any.toml")
    check_graph(reads_target).plan(("r1",), "navigation")
    with pytest.raises(GraphError, match="reads 'sense/target', which the world publishes only in navigation"):
        check_graph(reads_target).plan(("r1",), "tracking")


def test_malformed_files_name_the_field(write):
    with pytest.raises(GraphError, match="not valid TOML"):
        load_graph(write("[graph\n"))
    with pytest.raises(GraphError, match=r"node 'x'.evrey: unknown field"):
        load_graph(write(HEAD + '[[node]]\nname = "x"\nprogram = "p"\nevrey = 1\n'))
    with pytest.raises(GraphError, match=r"node 'x'.every: .*whole number of ticks"):
        load_graph(write(HEAD + '[[node]]\nname = "x"\nprogram = "p"\nevery = 0.5\n'))
    with pytest.raises(GraphError, match="delay = 1"):
        load_graph(write(HEAD + '[[node]]\nname = "x"\nprogram = "p"\ninputs = '
                                '{ s = { key = "share", from = "teammates", delay = 0 } }\n'))
    with pytest.raises(GraphError, match="uses {i} but the node has no instances"):
        load_graph(write(HEAD + '[[node]]\nname = "x"\nprogram = "p"\noutputs = { y = "out/{i}" }\n'))
    with pytest.raises(GraphError, match="no shipped graph of that name"):
        load_graph("no-such-graph")


@pytest.mark.parametrize("name", sorted(shipped_graphs()))
def test_every_shipped_graph_checks_for_teams_of_one_to_eight(name):
    checked = check_graph(name)
    tasks = ["navigation", "tracking"] if checked.graph.task == "any" else [checked.graph.task]
    for task in tasks:
        for n in (1, 3, 8):
            team = tuple(f"r{i + 1}" for i in range(n))
            plan = checked.plan(team, task)
            assert plan.warnings == []
            assert set(plan.nodes) == set(team) and len(plan.tokens()) == n * len(plan.nodes["r1"])


def test_graph_list_names_every_shipped_graph_in_aligned_columns():
    from click.testing import CliRunner

    from cekm_swarm.node.graph_commands import graph_group

    out = CliRunner().invoke(graph_group, ["list"])
    assert out.exit_code == 0, out.output
    lines = out.output.splitlines()
    assert [line.split()[0] for line in lines] == sorted(shipped_graphs())
    assert len({line.index("--controller") for line in lines}) == 1  # one column, however long a name


def test_a_program_whose_own_import_fails_is_not_called_unknown(write, tmp_path):
    """The module exists, and an import of its own fails: named as such, with its file and line."""
    (tmp_path / "graph_test_broken.py").write_text("import no_such_package_of_mine\n")
    text = refused(write(HEAD + SOURCE + WHEELS.replace(f"{P}:Wheels", "graph_test_broken:Wheels")),
                   "program 'graph_test_broken:Wheels' failed to import: ModuleNotFoundError: "
                   "No module named 'no_such_package_of_mine' (graph_test_broken.py:1)")
    assert "unknown program" not in text
    refused(write(HEAD + SOURCE + WHEELS.replace(f"{P}:Wheels", "graph_test_nowhere:Wheels")),
            "unknown program 'graph_test_nowhere:Wheels': cannot import 'graph_test_nowhere'")
