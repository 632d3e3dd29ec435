"""Bad arguments to every ``cekm`` command end in one line on stderr, in one style, with
the documented exit code, and never a traceback; ``--out`` never mixes two runs."""

from __future__ import annotations

from pathlib import Path

import click
import pytest

from cekm_swarm.cli import main
from cekm_swarm.cli_support import SEED, Interrupted, prepare_out_dir, run_cli
from cekm_swarm.errors import CekmError, OutputDirError, RunError


def leaf_commands(group: click.Group = main, path: tuple[str, ...] = ()) -> list[tuple[tuple[str, ...], click.Command]]:
    out = []
    for name, cmd in sorted(group.commands.items()):
        if isinstance(cmd, click.Group):
            out += leaf_commands(cmd, path + (name,))
        else:
            out.append((path + (name,), cmd))
    return out


COMMANDS = leaf_commands()


def one_error_line(capsys, argv: list[str], code: int = 2, kind: str = "error") -> str:
    """Run ``cekm argv``; assert the exit code and exactly one stderr line of the style."""
    assert run_cli(main, argv) == code
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"cekm: {kind}: "), lines[0]
    return lines[0]


def test_every_command_is_covered():
    names = {" ".join(p) for p, _ in COMMANDS}
    assert {"run", "launch", "train", "experiment target-reaching", "experiment obstacles", "sweep concave",
            "fields", "plot"} <= names


@pytest.mark.parametrize("path", [p for p, _ in COMMANDS], ids=lambda p: " ".join(p))
def test_an_unknown_option_is_a_usage_error_naming_it(capsys, path):
    line = one_error_line(capsys, [*path, "--no-such-option"])
    assert "--no-such-option" in line and f"cekm {' '.join(path)} --help" in line


@pytest.mark.parametrize("path", [p for p, c in COMMANDS if any(q.required for q in c.params)],
                         ids=lambda p: " ".join(p))
def test_a_missing_required_argument_is_a_usage_error(capsys, path):
    one_error_line(capsys, list(path))


def valid_argv(cmd: click.Command, tmp_path) -> list[str]:
    """The required arguments of ``cmd`` with values that pass its parser."""
    existing = tmp_path / "exists.bin"
    existing.write_bytes(b"")
    values = {"scenario": "lone_obstacle", "out_dir": str(tmp_path / "new-out"), "out_path": str(tmp_path / "o.png"),
              "at_time": "1", "key_expr": "cekm/**", "log_file": str(existing), "log": str(existing),
              "key": "cekm/r1/cmd/wheels", "message": "{}", "graph": "cekm-navigation",
              "out_file": str(tmp_path / "out.mcap"), "to": "ros2", "results": str(existing),
              "node": "r1/motor", "name": "speed", "value": "0.1"}
    argv: list[str] = []
    for p in cmd.params:
        if p.required:
            if isinstance(p, click.Argument):
                argv.append(values[p.name])
            else:
                argv += [p.opts[0], values[p.name]]
    return argv


def bad_values(param: click.Parameter) -> list[str]:
    """Values the parameter's type must refuse."""
    t = param.type
    if t is SEED:
        return ["-1", "x"]
    if isinstance(t, (click.IntRange, click.FloatRange)):
        return [str(b) for b in (None if t.min is None else t.min - 1, None if t.max is None else t.max + 1)
                if b is not None] + ["x"]
    if isinstance(t, click.Choice):
        return ["no-such-choice"]
    if t in (click.INT, click.FLOAT):
        return ["x"]
    if isinstance(t, click.Path) and t.exists:
        return ["/no/such/path"]
    if getattr(t, "name", "") == "endpoint":
        return ["a*b", "tcp/127.0.0.1:99999", "tcp/127.0.0.1:0"]
    if getattr(t, "name", "") in ("root", "run id"):
        return ["a*b"]
    if getattr(t, "name", "") == "size":
        return ["0", "12Q"]
    return []


CASES = [(path, p.opts[0], bad) for path, c in COMMANDS for p in c.params
         if isinstance(p, click.Option) and not p.is_flag for bad in bad_values(p)]


@pytest.mark.parametrize("path,option,bad", CASES, ids=lambda v: " ".join(v) if isinstance(v, tuple) else str(v))
def test_a_bad_option_value_is_refused_by_name_before_the_command_runs(capsys, tmp_path, monkeypatch, path, option,
                                                                      bad):
    cmd = dict(COMMANDS)[path]
    ran = []
    monkeypatch.setattr(cmd, "callback", lambda **kw: ran.append(kw))  # the checks are the parser's: nothing runs
    argv = valid_argv(cmd, tmp_path)
    line = one_error_line(capsys, [*path, *argv, option, bad])
    assert option in line and not ran


@pytest.mark.parametrize("argv,needle", [
    (["run", "no_such_scenario", "--out", "{out}"], "no such scenario"),
    (["run", "concave", "--controller", "acmommt", "--out", "{out}"], "(controllers: cekm, cekm-learning, "
                                                                      "cekm-learning-team, cekm-tuned, fusion, "
                                                                      "stay;"),
    (["run", "tracking", "--controller", "fusion", "--out", "{out}"],
     "(controllers: acmommt, cekm, kmeans, kmeans-global, stay;"),
    (["graph", "check", "/"], "/: is a directory, not a graph file"),
    (["view", "crossing", "--seed", "-1", "--wait", "0"], "--seed"),
    (["launch", "lone_obstacle", "--robots", "r9", "--out", "{out}"], "no robot r9"),
    (["launch", "lone_obstacle", "--no-world", "--robots", "none", "--out", "{out}"], "--no-world"),
    (["launch", "lone_obstacle", "--listen", "not a host!", "--out", "{out}"], "--listen"),
    (["launch", "lone_obstacle", "--robots", "", "--out", "{out}"], "--robots"),
    (["launch", "crossing", "--robots", "r1,r1", "--out", "{out}"], "r1 given twice"),
    (["graph", "acl", "cekm-navigation", "--robots", "0", "--out", "{out}/acl.json5"], "--robots"),
    (["graph", "acl", "cekm-navigation", "--robots", "-3", "--out", "{out}/acl.json5"], "robot id '-3'"),
    (["graph", "acl", "cekm-navigation", "--robots", "r 1,r/x", "--out", "{out}/acl.json5"], "robot id 'r 1'"),
    (["graph", "acl", "cekm-navigation", "--robots", "r1,r1", "--out", "{out}/acl.json5"], "r1 given twice"),
    (["ros2", "bridge", "--robots", "r1,r1", "--wait", "0"], "r1 given twice"),
    (["ros2", "bridge", "--teleop", "r 1", "--wait", "0"], "robot id 'r 1'"),
    (["fields", "lone_obstacle", "--at", "1", "--robot", "r9", "--out", "{out}/f.png"], "no robot 'r9'"),
    (["fields", "tracking", "--at", "3", "--out", "{out}/f.png"], "tracking is not supported"),
    (["sweep", "concave", "--seeds", "1,-2", "--out", "{out}"], "--seeds"),
    (["sweep", "concave", "--depths", "x", "--out", "{out}"], "--depths"),
    (["sweep", "concave", "--depths", "100", "--out", "{out}"], "--depths"),
    (["sweep", "concave", "--ranges", "99", "--out", "{out}"], "--ranges"),
    (["sweep", "concave", "--depths", "-0.1", "--out", "{out}"], "--depths"),
    (["sweep", "concave", "--depths", "nan", "--out", "{out}"], "--depths"),
    (["sweep", "concave", "--seeds", "", "--out", "{out}"], "--seeds: give at least one seed"),
    (["sweep", "concave", "--seeds", "1", "--need", "2", "--out", "{out}"], "--need"),
    (["experiment", "obstacles", "--seeds", "1", "--speed-unit", "1e-320", "--out", "{out}"], "--speed-unit"),
    (["experiment", "obstacles", "--seeds", "a", "--out", "{out}"], "--seeds"),
    (["experiment", "obstacles", "--seeds", "1,1", "--out", "{out}"], "--seeds: seed 1 given twice"),
    (["experiment", "obstacles", "--seeds", "1-3,2-4", "--out", "{out}"], "--seeds: seeds 2, 3 given twice"),
    (["experiment", "obstacles", "--seeds", "1-", "--out", "{out}"], "--seeds: range '1-' has no end"),
    (["sweep", "concave", "--seeds", "1,1", "--need", "2", "--out", "{out}"], "--seeds: seed 1 given twice"),
    (["topic", "pub", "cekm/r1/mine", '{"kind": "data", "values": {"x": "%s"}}' % ("a" * 40000), "--wait", "0",
      "--connect", "tcp/127.0.0.1:7812"], "the message is 40,058 bytes, over the 32 KB limit"),
    (["experiment", "target-reaching", "--seed", "4294967295", "--master-seeds", "2", "--out", "{out}"],
     "'--seed': 4294967295 with --master-seeds 2 runs seeds up to 4294967296"),
    (["experiment", "target-reaching", "--networks", "Q9", "--out", "{out}"], "Q9"),
    (["train", "--network", "Z1", "--out", "{out}/m.npz"], "Invalid value for '--network': unknown network 'Z1'"),
    (["experiment", "circling", "--network", "X7", "--out", "{out}"], "'--network': unknown network 'X7'"),
    (["experiment", "target-reaching", "--networks", "X7", "--out", "{out}"], "'--networks': unknown network"),
    (["experiment", "target-reaching", "--steps", "100", "--out", "{out}"],
     "--steps (100) must be a multiple of --test-interval (10000)"),
    (["experiment", "circling", "--steps", "10001", "--out", "{out}"], "'--steps': 10001"),
    (["experiment", "circling", "--target", "99", "--out", "{out}"], "'--target': 99"),
])
def test_values_checked_in_the_command_are_named_too(capsys, tmp_path, argv, needle):
    line = one_error_line(capsys, [a.replace("{out}", str(tmp_path / "out")) for a in argv])
    assert needle in line
    assert not (tmp_path / "out").exists()  # refused before anything was written


MIXED = """name = "mixed"
[arena]
bounds = [0.0, 0.0, 2.0, 2.0]
[[robots]]
id = "a"
start = [0.5, 0.5, 0.0]
goal = "t1"
[[robots]]
id = "b"
start = [1.5, 0.5, 0.0]
[[targets]]
id = "t1"
position = [1.0, 1.5]
"""


@pytest.mark.parametrize("command", ["run", "launch"])
def test_a_scenario_neither_for_tracking_nor_for_navigation_is_refused_by_robot(capsys, tmp_path, command):
    scenario = tmp_path / "mixed.toml"
    scenario.write_text(MIXED)
    line = one_error_line(capsys, [command, str(scenario), "--out", str(tmp_path / "out")])
    assert f"{scenario}: robots[1].goal: robot 'b' has none while 'a' has one" in line
    assert not (tmp_path / "out").exists()


UNBOUNDED = """
name = "unbounded"
[arena]
bounds = [0.0, 0.0, 2.0, 2.0]
[[robots]]
id = "a"
start = [0.5, 0.5, 0.0]
[[targets]]
id = "t1"
position = [1.0, 1.5]
"""


@pytest.mark.parametrize("command", ["run", "launch"])
def test_a_tracking_scenario_with_no_target_range_is_refused_by_field_before_anything_is_written(capsys, tmp_path,
                                                                                                 command):
    """target_range defaults to inf, which tracking cannot use (every target always seen):
    one line naming the file and the field, from both entry points, and no --out made."""
    scenario = tmp_path / "unbounded.toml"
    scenario.write_text(UNBOUNDED)
    line = one_error_line(capsys, [command, str(scenario), "--out", str(tmp_path / "out")])
    assert line.startswith(f"cekm: error: {scenario}: sensors.target_range: a tracking scenario (no robot has a goal) "
                           "needs a finite target sensing range, got inf (the default when [sensors] leaves it out); "
                           "e.g. target_range = 0.5"), line
    assert not (tmp_path / "out").exists()


ENCLOSED = """
name = "enclosed"
plan_checkpoints = true
[arena]
bounds = [0.0, 0.0, 2.0, 2.0]
[[robots]]
id = "r1"
start = [0.3, 0.3, 0.0]
goal = "g"
[[targets]]
id = "g"
position = [1.5, 1.5]
[[walls]]
a = [1.2, 1.2]
b = [1.8, 1.2]
[[walls]]
a = [1.8, 1.2]
b = [1.8, 1.8]
[[walls]]
a = [1.8, 1.8]
b = [1.2, 1.8]
[[walls]]
a = [1.2, 1.8]
b = [1.2, 1.2]
"""


@pytest.mark.parametrize("command", ["run", "launch"])
def test_a_goal_the_known_walls_close_off_is_refused_by_robot_when_checkpoints_are_planned(capsys, tmp_path, command):
    scenario = tmp_path / "enclosed.toml"
    scenario.write_text(ENCLOSED)
    line = one_error_line(capsys, [command, str(scenario), "--out", str(tmp_path / "out")])
    assert line.startswith(f"cekm: error: {scenario}: robots[0].goal: no path from (0.3, 0.3) to (1.5, 1.5) on the "
                           "known walls (plan_checkpoints = true needs one for every robot)"), line
    assert not (tmp_path / "out").exists()


def test_a_non_empty_out_directory_is_refused_and_left_alone(capsys, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "trajectory.png").write_bytes(b"old run")
    line = one_error_line(capsys, ["run", "lone_obstacle", "--out", str(out)])
    assert f"--out {out}: not empty" in line and "--overwrite" in line
    assert (out / "trajectory.png").read_bytes() == b"old run"


def test_an_out_whose_parents_are_missing_is_made_and_said(tmp_path, capsys):
    out = tmp_path / "runs" / "today" / "one"
    assert prepare_out_dir(out, overwrite=False) == out and out.is_dir()
    assert capsys.readouterr().err == f"note: --out {out}: created its missing parent {tmp_path / 'runs'}\n"
    prepare_out_dir(tmp_path / "two", overwrite=False)  # its parent is there: nothing said
    assert capsys.readouterr().err == ""


def test_overwrite_clears_the_directory_first(tmp_path):
    out = tmp_path / "out"
    (out / "logs").mkdir(parents=True)
    (out / "logs" / "r9-motor.log").write_text("an old robot's log")
    (out / "trajectory.png").write_bytes(b"another scenario's picture")
    assert prepare_out_dir(out, overwrite=True) == out
    assert list(out.iterdir()) == []
    (tmp_path / "f").write_text("x")
    with pytest.raises(OutputDirError, match="not a directory"):
        prepare_out_dir(tmp_path / "f", overwrite=True)


def test_overwrite_refuses_to_clear_the_working_directory(tmp_path, monkeypatch):
    (tmp_path / "keep").write_text("x")
    monkeypatch.chdir(tmp_path)
    for target in (tmp_path, tmp_path.parent):
        with pytest.raises(OutputDirError, match="refusing to clear"):
            prepare_out_dir(target, overwrite=True)
    assert (tmp_path / "keep").exists()


@click.group()
def toy() -> None:
    pass


@toy.command()
@click.option("--what")
def fail(what: str) -> None:
    raise {"run": RunError("the router went away"), "input": CekmError("model.npz: field 'W': bad shape"),
           "interrupt": KeyboardInterrupt(), "interrupted": Interrupted(),
           "multi": RunError("line one\nline two")}[what]


@pytest.mark.parametrize("what,code,start", [
    ("run", 1, "cekm: failed: the router went away"),
    ("input", 2, "cekm: error: model.npz: field 'W': bad shape"),
    ("interrupt", 130, "cekm: interrupted"),
    ("interrupted", 130, "cekm: interrupted"),
    ("multi", 1, "cekm: failed: line one line two"),
])
def test_exit_codes_and_one_line_per_kind_of_failure(capsys, what, code, start):
    assert run_cli(toy, ["fail", "--what", what]) == code
    err = capsys.readouterr().err
    assert [line for line in err.splitlines() if line] == [start]  # (click ends a Ctrl-C's line first)


def test_help_and_version_exit_0(capsys):
    assert run_cli(main, ["--help"]) == 0
    assert run_cli(main, ["launch", "--help"]) == 0
    assert "--overwrite" in capsys.readouterr().out


def test_every_float_option_refuses_nan_and_infinity():
    """float() and click's ranges take 'nan' and 'inf'; every float option is Finite."""
    from cekm_swarm.cli_support import Finite

    floats = [(" ".join(path), p.name) for path, cmd in COMMANDS for p in cmd.params
              if isinstance(p.type, click.types.FloatParamType)]
    assert floats and all(isinstance(p.type, Finite) for _, cmd in COMMANDS for p in cmd.params
                          if isinstance(p.type, click.types.FloatParamType)), floats


@pytest.mark.parametrize("argv", [["run", "crossing", "--max-time", "inf"], ["log", "cat", "x.mcap", "--start", "nan"],
                                  ["launch", "crossing", "--max-time", "nan"]])
def test_a_non_finite_number_is_a_usage_error_naming_the_option(capsys, tmp_path, argv):
    if argv[:2] == ["log", "cat"]:
        (tmp_path / "x.mcap").write_bytes(b"")
        argv = ["log", "cat", str(tmp_path / "x.mcap"), *argv[3:]]
    line = one_error_line(capsys, argv)
    assert f"Invalid value for '{argv[-2]}'" in line and "is not a finite number" in line


@pytest.mark.parametrize("argv", [
    ["sweep", "concave", "--depths", "100"],
    ["experiment", "obstacles", "--seeds", "1", "--speed-unit", "1e-320"],
    ["launch", "crossing", "--model", "{bad}", "--port", "7711"],
    ["run", "crossing", "--model", "{bad}"],
    ["experiment", "obstacles", "--seeds", "1", "--model", "{bad}"],
    ["launch", "concave", "--connect", "tcp/127.0.0.1:99999"],
])
def test_overwrite_clears_nothing_when_an_argument_is_bad(capsys, tmp_path, argv):
    """docs/running.md: a typo never costs you the previous results."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "results.json").write_text("the previous results")
    (tmp_path / "bad.npz").write_text("not a model")
    one_error_line(capsys, [*(a.replace("{bad}", str(tmp_path / "bad.npz")) for a in argv), "--out", str(out),
                            "--overwrite"])
    assert (out / "results.json").read_text() == "the previous results"


@pytest.mark.parametrize("argv", [
    ["run", "crossing", "--max-time", "2", "--out", "{file}/sub"],
    ["launch", "crossing", "--port", "7713", "--out", "{file}/sub"],
    ["experiment", "tracking", "--out", "{file}/sub"],
    ["experiment", "obstacles", "--seeds", "1", "--out", "{file}/sub"],
    ["sweep", "concave", "--out", "{file}/sub"],
    ["fields", "concave", "--at", "1", "--out", "{file}/f.png"],
    ["train", "--steps", "10", "--out", "{file}/m.npz"],
    ["graph", "acl", "cekm-navigation", "--out", "{file}/acl.json5"],
    ["plot", "{file}", "--out", "{file}/p.png"],
])
def test_an_out_that_cannot_be_created_is_one_line_naming_it(capsys, tmp_path, argv):
    """A parent that is a regular file was a NotADirectoryError/FileExistsError traceback."""
    file = tmp_path / "file.txt"
    file.write_text("a file, not a directory")
    line = one_error_line(capsys, [a.replace("{file}", str(file)) for a in argv])
    assert f"--out {file}/" in line and "is not a directory" in line.replace("Not a directory", "is not a directory")


def test_an_out_the_os_refuses_names_the_reason(tmp_path):
    from cekm_swarm.cli_support import prepare_out_file

    with pytest.raises(OutputDirError, match=r"--out /proc/cekm-no-such/x: cannot create the directory: "):
        prepare_out_dir(Path("/proc/cekm-no-such/x"), overwrite=False)
    with pytest.raises(OutputDirError, match=r"--out /proc/cekm-f.png: cannot write the file: "):
        prepare_out_file(Path("/proc/cekm-f.png"))
    with pytest.raises(OutputDirError, match="is a directory"):
        prepare_out_file(tmp_path)


def test_no_help_text_shows_a_bound_of_none():
    """A Finite option with no bounds showed '[x<=None]' in --help (QA item 3)."""
    ctx = click.Context(main)
    for path, cmd in COMMANDS:
        for p in cmd.params:
            if isinstance(p, click.Option):
                record = p.get_help_record(ctx)
                assert record is None or "None]" not in record[1] and "None;" not in record[1], (path, record)


@pytest.mark.parametrize("argv", [
    ["log", "info", "{log}"],
    ["log", "cat", "{log}"],
    ["replay", "{log}", "--port", "7809"],
    ["replay", "{log}", "--connect", "tcp/127.0.0.1:7809"],
    ["plot", "{log}", "--out", "{tmp}/p.png"],
    ["view", "--log", "{log}", "--wait", "0"],
])
def test_a_log_that_is_not_mcap_is_a_failure_naming_the_log(capsys, tmp_path, monkeypatch, argv):
    """docs/tools.md: 1 for a log it cannot read, the same line from every command (replay
    blamed CEKM_CONNECT or --connect, plot and replay said exit 2, view blamed a missing index)."""
    monkeypatch.delenv("CEKM_CONNECT", raising=False)
    log = tmp_path / "notmcap.mcap"
    log.write_text("hello\n")
    line = one_error_line(capsys, [a.replace("{log}", str(log)).replace("{tmp}", str(tmp_path)) for a in argv],
                          code=1, kind="failed")
    assert line == f"cekm: failed: {log}: not an MCAP file (bad magic)"


def test_no_world_without_robots_starts_every_robot(capsys, tmp_path, monkeypatch):
    """docs/tools.md: a robots-only host, `cekm launch SCENARIO --no-world --connect ...`:
    without --robots every robot is meant (it was refused as 'no robot here')."""
    from cekm_swarm.launch.launcher import Launcher

    seen = []

    def launch(self):
        seen.append((self.c.robots, self.c.world))
        return {}

    monkeypatch.setattr(Launcher, "launch", launch)
    assert run_cli(main, ["launch", "lone_obstacle", "--no-world", "--connect", "tcp/127.0.0.1:7810",
                          "--out", str(tmp_path / "out")]) == 0, capsys.readouterr().err
    assert seen == [(None, False)]


@pytest.mark.parametrize("argv", [
    ["fields", "concave", "--at", "3", "--out", "{out}/fig4.txt"],
    ["plot", "{log}", "--out", "{out}/x.txt"],
])
def test_a_figure_format_matplotlib_cannot_write_is_refused_before_any_work(capsys, tmp_path, monkeypatch, argv):
    """It was a ValueError traceback from savefig, after the work (QA item 13)."""
    import cekm_swarm.experiments.navigation_run as navigation_run

    monkeypatch.setattr(navigation_run, "fields_at", lambda *a, **k: pytest.fail("the run was computed"))
    log = tmp_path / "run.mcap"
    log.write_text("not read: the --out is refused first")
    line = one_error_line(capsys, [a.replace("{out}", str(tmp_path / "out")).replace("{log}", str(log))
                                   for a in argv])
    assert f"--out {tmp_path / 'out'}/" in line and "cannot write a figure as .txt (formats: " in line and "png" in line
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("argv,refused", [
    (["record", "--out", "{victim}", "--duration", "1", "--wait", "0"], "{victim}: exists"),
    (["record", "--out", "{dir}/run.mcap", "--max-log-size", "1M", "--wait", "0"],
     "{dir}/run_0.mcap .. run_1.mcap: a log set exists there"),
    (["log", "info", "{victim}", "--recover", "{victim}"], "{victim}: exists"),
    (["log", "recover", "{victim}", "{victim}"], "{victim}: exists"),
])
def test_an_existing_output_log_is_kept_unless_force(capsys, tmp_path, argv, refused):
    """A log cannot be made again: record and log info --recover overwrote one silently
    (QA item 14); log recover refused it. Refused before waiting for any router."""
    victim = tmp_path / "victim.mcap"
    victim.write_bytes(b"a run's only log")
    for k in range(2):
        (tmp_path / f"run_{k}.mcap").write_bytes(b"a set's file")
    fill = {"{victim}": str(victim), "{dir}": str(tmp_path)}

    def sub(a):
        for k, v in fill.items():
            a = a.replace(k, v)
        return a

    line = one_error_line(capsys, [sub(a) for a in argv], code=1, kind="failed")
    assert line == f"cekm: failed: {sub(refused)}; use --force to overwrite it"
    assert victim.read_bytes() == b"a run's only log" and (tmp_path / "run_1.mcap").read_bytes() == b"a set's file"


@pytest.mark.parametrize("text,problem", [("hello\n", "expected array, boolean, null, number, object, or string"),
                                          ("", "Empty config file")])
def test_a_bad_config_file_is_one_line_without_zenohs_source_location(capsys, tmp_path, text, problem):
    """Zenoh's error ended with its Rust source file on the build machine (QA item 11)."""
    config = tmp_path / "bad.json5"
    config.write_text(text)
    line = one_error_line(capsys, ["topic", "list", "--config", str(config), "--wait", "0"], code=1, kind="failed")
    assert line.startswith(f"cekm: failed: zenoh config {config}: ") and line.endswith(problem), line
