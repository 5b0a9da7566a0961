"""Release checklist of issue 11, items 2, 4 (bad output paths), 7 and 8: the live viewer listens on
127.0.0.1 only; bad output paths are found before planning; each weak error is one line naming the
argument, file or key (exit 2), API misuse a TypeError naming the argument (`verify(123)`,
`Hand.from_urdf(123)`); long work shows progress, `--help` shows defaults.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import importlib.util
import io
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from test_viewer import make_plan

from regrasp_casadi import cli, cli_tools

ROOT = Path(__file__).resolve().parents[1]
BOX_PROBLEM = ROOT / "problems" / "box_rotate.yaml"


def _env() -> dict[str, str]:
    """The environment of a `python -m regrasp_casadi.cli` subprocess that imports this checkout."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)
    return env


def _one_error_line(err: str, *names: str) -> str:
    """The single `regrasp: error:` line of `err`, which must name every one of `names`."""
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, f"expected one line on stderr, got:\n{err}"
    assert lines[0].startswith("regrasp: error: ") and "Traceback" not in err
    for name in names:
        assert name in lines[0], f"{name!r} not named in: {lines[0]}"
    return lines[0]


@pytest.fixture()
def plan_file(hand, tmp_path) -> Path:
    return make_plan(hand).save(tmp_path / "plan.json")


# ----------------------------------------------------------------------------- item 2: listening address
def _children(pid: int) -> list[int]:
    """Every descendant of process `pid` (from /proc/*/stat)."""
    parent = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        parent[int(stat.parent.name)] = int(fields[1])
    found, todo = [], [pid]
    while todo:
        p = todo.pop()
        kids = [c for c, pp in parent.items() if pp == p]
        found += kids
        todo += kids
    return found


def _address(hex_address: str) -> tuple[str, int]:
    """(ip, port) of a /proc/net/tcp{,6} address: the ip in 32-bit little-endian words, the port in hex."""
    import socket

    ip_hex, port_hex = hex_address.split(":")
    raw = b"".join(bytes.fromhex(ip_hex[i:i + 8])[::-1] for i in range(0, len(ip_hex), 8))
    return socket.inet_ntop(socket.AF_INET if len(raw) == 4 else socket.AF_INET6, raw), int(port_hex, 16)


def _listening(pids: list[int]) -> list[tuple[str, int]]:
    """(ip, port) of every listening TCP socket held by the processes `pids` (from /proc, Linux)."""
    found = []
    for pid in pids:
        inodes = set()
        try:
            for fd in Path(f"/proc/{pid}/fd").iterdir():
                with contextlib.suppress(OSError):
                    m = re.fullmatch(r"socket:\[(\d+)\]", os.readlink(fd))
                    if m:
                        inodes.add(m.group(1))
            tables = [Path(f"/proc/{pid}/net/{t}").read_text().splitlines()[1:] for t in ("tcp", "tcp6")]
        except OSError:   # the process has ended
            continue
        for line in (ln for table in tables for ln in table):
            f = line.split()
            if f[3] == "0A" and f[9] in inodes:   # state 0A: LISTEN
                found.append(_address(f[1]))
    return found


def test_live_viewer_listens_on_loopback_only(plan_file):
    """`regrasp view PLAN` (the live viewer): every listening socket of the CLI and of its Meshcat server
    is on 127.0.0.1, the printed URL's port among them; SIGTERM stops both (all within 60 s)."""
    proc = subprocess.Popen([sys.executable, "-m", "regrasp_casadi.cli", "view", str(plan_file)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env())
    try:
        deadline = time.monotonic() + 60
        line = proc.stdout.readline()   # "viewer: http://127.0.0.1:7000/static/  (Ctrl-C to stop)"
        assert line.startswith("viewer: "), line + proc.stderr.read()
        url_port = int(re.search(r"http://127\.0\.0\.1:(\d+)/", line).group(1))
        pids = [proc.pid, *_children(proc.pid)]
        assert len(pids) > 1, "no Meshcat server process"
        sockets = _listening(pids)
        while url_port not in {port for _, port in sockets} and time.monotonic() < deadline:
            time.sleep(0.2)
            sockets = _listening(pids)
        assert url_port in {port for _, port in sockets}, sockets
        assert {ip for ip, _ in sockets} == {"127.0.0.1"}, sockets
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=20)
        finally:
            if proc.poll() is None:
                proc.kill()
    assert proc.returncode == 0
    assert not [p for p in pids[1:] if Path(f"/proc/{p}").exists()], "the Meshcat server outlived the CLI"


def test_proc_address_decoding():
    assert _address("0100007F:1B58") == ("127.0.0.1", 7000)
    assert _address("00000000000000000000000001000000:1B58") == ("::1", 7000)
    assert _address("00000000:1770") == ("0.0.0.0", 6000)


def test_live_viewer_host_is_checked_before_work(plan_file, capsys):
    assert cli.main(["view", str(plan_file), "--host", "no-such-host.invalid"]) == cli.EXIT_BAD_INPUT
    _one_error_line(capsys.readouterr().err, "--host", "no-such-host.invalid")


# ------------------------------------------------------------------ item 4: bad output paths, before work
def _no_planning(monkeypatch) -> list:
    """Record every problem load and plan made through the CLI."""
    import regrasp_casadi.planner as planner_mod
    import regrasp_casadi.problem as problem_mod

    calls: list = []
    monkeypatch.setattr(planner_mod, "plan_regrasp", lambda *a, **k: calls.append("plan"))
    real_load = problem_mod.RegraspProblem.load.__func__
    monkeypatch.setattr(problem_mod.RegraspProblem, "load",
                        classmethod(lambda cls, p: (calls.append("load"), real_load(cls, p))[1]))
    return calls


def _bad_paths(tmp_path: Path) -> list[tuple[str, Path]]:
    a_file = tmp_path / "a_file.txt"
    a_file.write_text("not a folder\n", encoding="utf-8")
    bad = [("a folder", tmp_path), ("under a file", a_file / "plan.json"),
           ("in /proc", Path("/proc/regrasp_no_such_dir/plan.json"))]
    if os.geteuid() != 0:   # root may write in a read-only folder
        ro = tmp_path / "read_only"
        ro.mkdir(mode=0o500)
        bad.append(("read-only folder", ro / "plan.json"))
    return bad


@pytest.mark.parametrize("option", ["--out", "--html"])
def test_bad_output_path_is_found_before_planning(option, tmp_path, capsys, monkeypatch):
    calls = _no_planning(monkeypatch)
    for what, path in _bad_paths(tmp_path):
        t0 = time.perf_counter()
        code = cli.main(["plan", str(BOX_PROBLEM), option, str(path), "--no-progress"])
        assert time.perf_counter() - t0 < 1.0, what
        assert code == cli.EXIT_BAD_INPUT, what
        _one_error_line(capsys.readouterr().err, option, str(path))
    assert calls == []


def test_bad_output_paths_of_other_commands(plan_file, tmp_path, capsys, monkeypatch):
    calls = _no_planning(monkeypatch)
    a_file = tmp_path / "a_file.txt"
    a_file.write_text("x", encoding="utf-8")
    for argv, option in [(["view", str(plan_file), "--html", str(tmp_path)], "--html"),
                         (["view", str(plan_file), "--png", str(a_file / "x.png")], "--png"),
                         (["grasps", str(BOX_PROBLEM), "--out", str(tmp_path)], "--out"),
                         (["demo", "--out-dir", str(a_file)], "--out-dir")]:
        assert cli.main(argv) == cli.EXIT_BAD_INPUT, argv
        _one_error_line(capsys.readouterr().err, option)
    assert calls == []


# ----------------------------------------------------------------------------------- item 7: weak errors
def _problem_text() -> str:
    return BOX_PROBLEM.read_text(encoding="utf-8")


@pytest.mark.parametrize(("name", "make", "names"), [
    ("latin1.yaml", lambda t: t.replace("box_rotate", "b\u00f6x").encode("latin-1"),
     ["latin1.yaml", "UTF-8"]),
    ("dup.yaml", lambda t: re.sub(r"(?m)^(  extents: .*)$", r"\1\n\1", t).encode(),
     ["dup.yaml", "'extents'"]),
    ("dup_top.yaml", lambda t: t.replace("\nhand: ", "\nhand: allegro_right\nhand: ").encode(),
     ["dup_top.yaml", "'hand'"]),
    ("no_extents.yaml", lambda t: re.sub(r"(?m)^  extents: .*\n", "", t).encode(),
     ["no_extents.yaml", "object", "extents"]),
])
def test_bad_problem_files_give_one_line(name, make, names, tmp_path, capsys):
    assert "extents" in _problem_text() and "\nhand: " in _problem_text()
    path = tmp_path / name
    path.write_bytes(make(_problem_text()))
    assert cli.main(["plan", str(path), "--out", str(tmp_path / "p.json"), "--no-progress"]) == 2
    _one_error_line(capsys.readouterr().err, *names)
    assert not (tmp_path / "p.json").exists()


@pytest.mark.parametrize(("primitive", "given", "missing"), [
    ("cylinder", {"radius": 0.03}, "height"),
    ("sphere", {}, "radius"),
    ("bottle", {"body_radius": 0.03, "body_height": 0.12}, "shoulder_height"),
])
def test_every_primitive_needs_its_dimensions(primitive, given, missing, tmp_path):
    import yaml

    from regrasp_casadi.errors import ProblemFileError
    from regrasp_casadi.problem import RegraspProblem

    doc = yaml.safe_load(_problem_text())
    doc["object"] = {"primitive": primitive, **given}
    path = tmp_path / "p.yaml"
    path.write_text(yaml.safe_dump(doc), encoding="utf-8")
    with pytest.raises(ProblemFileError, match=rf"^{re.escape(str(path))}: object: .*missing key.*{missing}"):
        RegraspProblem.load(path)


@pytest.mark.parametrize(("argv", "names"), [
    (["plan", str(BOX_PROBLEM), "--max-iters", "-1"], ["--max-iters", "-1"]),
    (["grasps", str(BOX_PROBLEM), "--n", "-3"], ["--n", "-3"]),
    (["grasps", str(BOX_PROBLEM), "--n", "two"], ["--n", "two"]),
    (["grasps", "mesh.obj", "--scale", "0"], ["--scale"]),
    (["view", "plan.json", "--png", "x.png", "--at", "-1"], ["--at"]),
    (["plan"], ["PROBLEM.yaml"]),
])
def test_bad_arguments_give_one_line(argv, names, capsys, monkeypatch):
    calls = _no_planning(monkeypatch)
    assert cli.main(argv) == cli.EXIT_BAD_INPUT
    _one_error_line(capsys.readouterr().err, *names)
    assert calls == []


@pytest.fixture(scope="module")
def box_problem():
    from regrasp_casadi.problem import RegraspProblem

    return RegraspProblem.load(BOX_PROBLEM)


def test_api_misuse_names_the_argument(box_problem):
    from regrasp_casadi.errors import GraspError
    from regrasp_casadi.grasp import Grasp, require_grasp

    p, g0 = box_problem, box_problem.grasp0
    with pytest.raises(GraspError, match=r"^q: expected 16 joint angles .*'abc'"):
        Grasp.from_joints(p.hand, p.obj, "abc", g0.T_palm_object)
    with pytest.raises(GraspError, match=r"^T_palm_object: expected a \(4, 4\)"):
        Grasp.from_joints(p.hand, p.obj, g0.q, [["a"] * 4] * 4)
    with pytest.raises(GraspError, match=r"^contacts_object: expected \(4, 3\)"):
        Grasp.from_contacts(p.hand, p.obj, "abc", g0.T_palm_object)
    with pytest.raises(TypeError, match=r"^hand: expected a regrasp_casadi Hand, got NoneType"):
        Grasp.from_joints(None, p.obj, g0.q, g0.T_palm_object)
    with pytest.raises(TypeError, match=r"^obj: expected a regrasp_casadi ObjectModel, got str"):
        Grasp.from_contacts(p.hand, "box.obj", g0.contacts_object, g0.T_palm_object)
    with pytest.raises(TypeError, match=r"^grasp_goal: expected a Grasp"):
        require_grasp(None, "grasp_goal")
    assert require_grasp(g0, "grasp0") is g0


def test_verify_takes_a_plan_or_a_plan_file_path(plan_file, tmp_path):
    """verify(path) reads the plan with Plan.load: the same report as verify(Plan.load(path)); anything
    else is a TypeError naming the argument."""
    from regrasp_casadi import verify
    from regrasp_casadi.errors import PlanFormatError
    from regrasp_casadi.plan import Plan

    expected = verify(Plan.load(plan_file))
    for given in (str(plan_file), plan_file):
        report = verify(given)
        assert report.ok == expected.ok and report.violations == expected.violations
    assert expected.violations   # the hand-made plan's contacts are tip centres, off the object
    with pytest.raises(TypeError, match=r"^plan: expected a Plan or a plan file path, got int$"):
        verify(123)
    with pytest.raises(TypeError, match=r"^plan: expected a Plan or a plan file path, got dict$"):
        verify(Plan.load(plan_file).to_dict())
    with pytest.raises(PlanFormatError, match=r"missing\.json"):
        verify(tmp_path / "missing.json")


def test_hand_from_urdf_names_its_argument(hand):
    from regrasp_casadi.hand import Hand

    with pytest.raises(TypeError, match=r"^path: expected a URDF file path, got int$"):
        Hand.from_urdf(123)
    with pytest.raises(TypeError, match=r"^path: expected a URDF file path, got NoneType$"):
        Hand.from_urdf(None)
    assert Hand.from_urdf(hand.urdf_path).fingers == hand.fingers   # a Path is a path
    assert Hand.from_urdf(str(hand.urdf_path)).fingers == hand.fingers


def test_planner_rejects_joints_off_the_contacts(box_problem):
    """A grasp0 whose q does not put the tips on its contacts is invalid input naming finger and distance."""
    from regrasp_casadi.grasp import Grasp
    from regrasp_casadi.planner import plan_regrasp

    p, g0, goal = box_problem, box_problem.grasp0, box_problem.grasp_goal
    assert g0.inconsistency() == "" and goal.inconsistency() == ""
    c = np.array(g0.contacts_object)
    r = p.hand.fingers.index("middle")
    c[r] += 0.002 * np.array([0.6, 0.0, 0.8])   # 2 mm from where the middle tip touches
    moved = dataclasses.replace(g0, contacts_object=c)
    assert re.fullmatch(r"grasp0: its joints q put the middle tip 2\.0 mm from its contact .*",
                        moved.inconsistency("grasp0"))
    plan = plan_regrasp(moved, goal)
    assert plan.status == "invalid_input" and not plan.steps
    assert "middle tip 2.0 mm" in plan.status_detail
    # goal contacts with the initial joints: the tips are not there
    mixed = Grasp.from_contacts(p.hand, p.obj, goal.contacts_object, g0.T_palm_object, q=g0.q)
    plan = plan_regrasp(mixed, goal)
    assert plan.status == "invalid_input"
    assert re.search(r"grasp0: its joints q put the (index|middle|ring|thumb) tip \d+\.\d mm",
                     plan.status_detail)
    assert plan_regrasp(g0, goal, method=3).status_detail.startswith("unknown method 3")


class _ClosedStdout(io.StringIO):
    def write(self, s):
        raise BrokenPipeError(32, "Broken pipe")


def test_closed_stdout_stops_quietly(plan_file, capsys, monkeypatch):
    monkeypatch.setattr(sys, "stdout", _ClosedStdout())
    assert cli.main(["verify", str(plan_file)]) == cli.EXIT_BROKEN_PIPE == 141
    assert capsys.readouterr().err == ""


def test_verify_into_a_closed_pipe_exits_quietly(plan_file):
    """`regrasp verify plan.json | head -0`: the reader is gone before verify prints."""
    proc = subprocess.Popen([sys.executable, "-m", "regrasp_casadi.cli", "verify", str(plan_file)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=_env())
    proc.stdout.close()   # no reader
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == cli.EXIT_BROKEN_PIPE, err
    assert err.decode().strip() == ""


@pytest.mark.browser
def test_screenshot_at_time_zero(plan_file, tmp_path, capsys):
    from regrasp_casadi.screenshot import find_chromium, screenshot

    with pytest.raises(ValueError, match="seconds"):
        screenshot(tmp_path / "x.html", tmp_path / "x.png", seconds=-1.0)
    if find_chromium() is None:
        pytest.skip("chromium not installed")
    t0 = time.perf_counter()
    assert cli.main(["view", str(plan_file), "--png", str(tmp_path / "t0.png"), "--at", "0"]) == 0
    assert time.perf_counter() - t0 < 60
    assert (tmp_path / "t0.png").stat().st_size > 1000
    assert "at 0.0 s" in capsys.readouterr().out


# ---------------------------------------------------------------------------- item 8: feedback, defaults
def test_planning_bar_ends_at_the_iterations_run(capsys, monkeypatch):
    import regrasp_casadi.planner as planner_mod
    from regrasp_casadi.cli_plan import run_plan

    def fake_plan(grasp0, grasp_goal, progress=None, **options):
        for it in (1, 2, 3):
            progress(it, 50, 0.004)
        return SimpleNamespace(iterations=3)

    monkeypatch.setattr(planner_mod, "plan_regrasp", fake_plan)
    plan = run_plan(SimpleNamespace(grasp0=None, grasp_goal=None), "svd", None, show_progress=True)
    assert plan.iterations == 3
    err = capsys.readouterr().err
    last = re.split(r"[\r\n]", err.strip())[-1]
    assert "100%" in last and "3/3" in last, err
    assert "3/50" in err   # the bar did run against max_iters until the plan stopped


def test_planning_bar_counts_on_through_a_restart(capsys, monkeypatch):
    """A first plan of 3 iterations, then a restart of 2 (its progress counted on, `restarts.continued`):
    the bar goes 3/50, then 4/53 and 5/53, and ends at 5/5, not at the returned plan's 2."""
    import regrasp_casadi.planner as planner_mod
    from regrasp_casadi.cli_plan import run_plan
    from regrasp_casadi.restarts import continued

    def fake_plan(grasp0, grasp_goal, progress=None, **options):
        for it in (1, 2, 3):
            progress(it, 50, 0.004)
        for it in (1, 2):
            continued(progress, 3)(it, 50, 0.002)
        return SimpleNamespace(iterations=2)

    monkeypatch.setattr(planner_mod, "plan_regrasp", fake_plan)
    run_plan(SimpleNamespace(grasp0=None, grasp_goal=None), "svd", None, show_progress=True)
    err = capsys.readouterr().err
    assert "3/50" in err and "5/53" in err
    last = re.split(r"[\r\n]", err.strip())[-1]
    assert "100%" in last and "5/5" in last, err


def test_progress_only_on_a_terminal(monkeypatch):
    class Tty(io.StringIO):
        def isatty(self):
            return True

    monkeypatch.setattr(sys, "stderr", io.StringIO())
    assert not cli_tools.progress_enabled(argparse.Namespace())
    monkeypatch.setattr(sys, "stderr", Tty())
    assert cli_tools.progress_enabled(argparse.Namespace())
    assert not cli_tools.progress_enabled(argparse.Namespace(quiet=True))
    assert not cli_tools.progress_enabled(argparse.Namespace(no_progress=True))
    assert cli.build_parser().parse_args(["verify", "x.json", "-q"]).quiet


def test_grasp_generation_reports_progress(hand):
    from regrasp_casadi.grasp_gen import generate_grasps
    from regrasp_casadi.objects import ObjectModel

    calls = []
    grasps = generate_grasps(hand, ObjectModel.box((0.05, 0.07, 0.12)), n=1, seed=0,
                             progress=lambda found, attempts: calls.append((found, attempts)))
    assert len(grasps) == 1
    assert [a for _, a in calls] == list(range(1, len(calls) + 1))   # after every attempt
    assert calls[-1][0] == 1 and all(f == 0 for f, _ in calls[:-1])


@pytest.mark.parametrize(("command", "defaults"), [
    ("plan", ["(default: svd)", "(default: plan.json)", "(default: 127.0.0.1)", "(default: 50"]),
    ("grasps", ["(default: 1)", "(default: 0)", "(default: 1.0)"]),
    ("demo", ["(default: svd)", "(default: none)", "(default: the current directory)"]),
])
def test_help_shows_defaults(command, defaults, capsys):
    assert cli.main([command, "--help"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    for d in defaults:
        assert d in out, f"{d} missing from `regrasp {command} --help`"
    assert "(default: None)" not in out and "(default: False)" not in out


def test_bench_takes_ycb_names(tmp_path, monkeypatch, capsys):
    spec = importlib.util.spec_from_file_location("paper_objects", ROOT / "benchmarks" / "paper_objects.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    assert {bench.object_label(y) for y in bench.OBJECTS.values()} == set(bench.OBJECTS)
    assert bench.object_label("sugar-box") == "sugar-box"
    monkeypatch.setattr(bench, "YCB_DIR", tmp_path / "no_ycb")   # stops right after parsing
    assert bench.main(["--objects", "004_sugar_box", "banana"]) == 2
    assert "YCB meshes not found" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        bench.main(["--objects", "005_tomato_soup_can"])


def test_plan_regrasp_names_the_argument_that_is_not_a_grasp():
    from regrasp_casadi.planner import plan_regrasp
    from regrasp_casadi.problem import RegraspProblem

    with pytest.raises(TypeError, match="grasp0: expected a Grasp"):
        plan_regrasp(None, None)
    problem = RegraspProblem.load(BOX_PROBLEM)
    with pytest.raises(TypeError, match="grasp_goal: expected a Grasp.*got dict"):
        plan_regrasp(problem.grasp0, {"contacts": []})
