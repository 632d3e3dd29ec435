"""The package's boundaries: the controller and the world meet only through plain data
and the message protocol; the numerical core does no I/O."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def imports_of(package: str) -> dict[str, set[str]]:
    out = {}
    for path in (ROOT / package.replace(".", "/")).rglob("*.py"):
        names = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names |= {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                if node.level:  # relative: resolve against the module's package
                    base = path.relative_to(ROOT).with_suffix("").parts[:-node.level]
                    names.add(".".join(base + ((node.module,) if node.module else ())))
                elif node.module:
                    names.add(node.module)
        out[str(path.relative_to(ROOT))] = names
    return out


def test_controller_and_models_never_import_the_world():
    for package in ("cekm_swarm.models", "cekm_swarm.controller"):
        for path, names in imports_of(package).items():
            assert not any(n == "world" or n.startswith("world.") for n in names), path


def test_the_controller_takes_plain_values_never_messages():
    """The pure controller is fed plain typed values (readings, poses, teammates' shares);
    the node modules and the in-process runner turn messages into them."""
    for path, names in imports_of("cekm_swarm.controller").items():
        bad = {n for n in names if n.startswith(("cekm_swarm.protocol", "cekm_swarm.node", "cekm_swarm.runtime",
                                                  "zenoh", "msgspec", "msgpack"))}
        assert not bad, (path, bad)


WORLD_MAY_IMPORT = (
    "cekm_swarm.protocol",
    "cekm_swarm.angles",
    "cekm_swarm.ticks",
    "cekm_swarm.errors",
    "cekm_swarm.jsonfile",
    "cekm_swarm.cli_support",
    "cekm_swarm.runtime",
    "cekm_swarm.robot",
    "cekm_swarm.graph.spec",
    "cekm_swarm.graph.plan",
    "cekm_swarm.graph.resolve",
    "cekm_swarm.graph.runspec",
)
"""What the world may import: the protocol, the transport, the two conventions, the robot's
body, strict JSON for its files, the command line's option types, and a graph as plain data
(the run spec) -- never node, controller or model code."""


def test_world_never_imports_controller_code():
    for path, names in imports_of("world").items():
        bad = {n for n in names if n.startswith("cekm_swarm") and not n.startswith(WORLD_MAY_IMPORT)}
        assert not bad, (path, bad)


def test_a_graph_as_data_imports_no_node_code():
    """The world reads graphs and run specs: their modules import only the protocol, the
    clock, the robot's body and each other; only the checks and the CLI import node programs."""
    allowed = ("cekm_swarm.protocol", "cekm_swarm.ticks", "cekm_swarm.errors", "cekm_swarm.robot",
               "cekm_swarm.graph.spec", "cekm_swarm.graph.plan", "cekm_swarm.graph.resolve", "cekm_swarm.graph.runspec",
               "cekm_swarm.graph")
    for path, names in imports_of("cekm_swarm.graph").items():
        if path.endswith(("check.py", "commands.py", "acl.py")):
            continue
        bad = {n for n in names if n.startswith("cekm_swarm") and not n.startswith(allowed)}
        assert not bad, (path, bad)


def test_nodes_never_import_the_world():
    for package in ("cekm_swarm.node", "cekm_swarm.modules", "cekm_swarm.graph"):
        for path, names in imports_of(package).items():
            assert not any(n == "world" or n.startswith("world.") for n in names), path


def test_module_processes_never_import_the_world():
    for path, names in imports_of("cekm_swarm.modules").items():
        assert not any(n == "world" or n.startswith("world.") for n in names), path


def test_runtime_never_imports_controller_code():
    # the world server may import the runtime, so the runtime must not reach the controller
    for path, names in imports_of("cekm_swarm.runtime").items():
        bad = {n for n in names if n.startswith(("cekm_swarm.controller", "cekm_swarm.models",
                                                 "cekm_swarm.experiments", "cekm_swarm.modules"))}
        assert not bad, (path, bad)


def test_numerical_core_does_no_io():
    io_modules = {"os", "pathlib", "json", "zenoh", "msgpack", "mcap", "socket", "subprocess"}
    for path, names in imports_of("cekm_swarm.models").items():
        if path.endswith("io.py"):  # the saved-model format is the core's one file boundary
            continue
        assert not (names & io_modules), (path, names & io_modules)


def _top_level_imports(path: Path) -> set[str]:
    names = set()
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names.add(node.module)
    return names


def test_experiments_keep_the_terminal_and_the_pictures_apart():
    """Only the experiments' command glue (``experiments/commands.py``) talks to the terminal
    with click; running, statistics, figures and reports import no click at all, and no
    experiment module imports matplotlib at module level (figures import it when drawing)."""
    for path, names in imports_of("cekm_swarm.experiments").items():
        if not path.endswith("commands.py"):
            assert not any(n == "click" or n.startswith("click.") for n in names), path
    for path in (ROOT / "cekm_swarm" / "experiments").glob("*.py"):
        top = _top_level_imports(path)
        assert not any(n == "matplotlib" or n.startswith("matplotlib.") for n in top), path


def test_the_ros2_plant_imports_neither_the_world_nor_controller_code():
    """The ROS 2 plant is the world's counterpart: it meets the graph only through the protocol."""
    for path, names in imports_of("cekm_swarm.ros2").items():
        if "/plant" not in path:
            continue
        bad = {n for n in names if n == "world" or n.startswith(("world.", "cekm_swarm.controller", "cekm_swarm.models",
                                                                  "cekm_swarm.modules", "cekm_swarm.node",
                                                                  "cekm_swarm.experiments", "cekm_swarm.launch"))}
        assert not bad, (path, bad)
