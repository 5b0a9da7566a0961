"""The `regrasp` command line: help texts, exit codes, one-line errors, and the plan -> HTML round trip."""

from __future__ import annotations

import base64
import dataclasses
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_viewer import make_plan

from regrasp_casadi import cli

HELP_NAMES = {
    None: ["plan", "verify", "view", "grasps", "bench", "demo", "exit codes"],
    "plan": ["PROBLEM.yaml", "--method", "--stability", "--out", "--html", "--view", "--max-iters",
             "--verbose"],
    "verify": ["PLAN.json", "--all", "--verbose"],
    "view": ["PLAN.json", "--html"],
    "grasps": ["MESH_OR_PROBLEM", "--n", "--seed", "--out"],
    "bench": ["ARGS"],
    "demo": ["--out-dir", "--method", "--stability"],
}


@pytest.mark.parametrize("command", list(HELP_NAMES))
def test_help_names_the_arguments(command, capsys):
    argv = ["--help"] if command is None else [command, "--help"]
    assert cli.main(argv) == 0
    out = capsys.readouterr().out
    for name in HELP_NAMES[command]:
        assert name in out, f"{name!r} missing from `regrasp {command or ''} --help`"
    assert "2    bad input" in out   # exit codes documented in every help text


def _one_error_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, f"expected one line on stderr, got:\n{err}"
    assert lines[0].startswith("regrasp: error: ")
    assert "Traceback" not in err
    return lines[0]


def test_missing_problem_file_is_bad_input(tmp_path, capsys):
    path = tmp_path / "nope" / "missing_problem.yaml"
    assert cli.main(["plan", str(path), "--out", str(tmp_path / "p.json")]) == cli.EXIT_BAD_INPUT
    line = _one_error_line(capsys.readouterr().err)
    assert "missing_problem.yaml" in line
    assert not (tmp_path / "p.json").exists()


def test_malformed_problem_file_is_bad_input(tmp_path, capsys):
    path = tmp_path / "broken.yaml"
    path.write_text("schema_version: 1\nhand: [unclosed\n", encoding="utf-8")
    assert cli.main(["plan", str(path), "--no-progress"]) == cli.EXIT_BAD_INPUT
    assert "broken.yaml" in _one_error_line(capsys.readouterr().err)


def test_verbose_shows_the_traceback(tmp_path, capsys):
    for argv in (["plan", str(tmp_path / "missing.yaml"), "--verbose"],
                 ["--verbose", "plan", str(tmp_path / "missing.yaml")]):
        assert cli.main(argv) == cli.EXIT_BAD_INPUT
        err = capsys.readouterr().err
        assert "Traceback" in err and err.rstrip().splitlines()[-1].startswith("regrasp: error: ")


def test_bad_arguments_exit_2(capsys):
    assert cli.main(["plan"]) == 2
    assert cli.main(["plan", "x.yaml", "--method", "newton"]) == 2
    assert cli.main([]) == 2


def planted_plan(hand):
    """A plan whose last step puts joint 1 (index) 0.3 rad above its upper limit."""
    plan = make_plan(hand)
    last = plan.steps[-1]
    q = last.q.copy()
    q[1] = hand.q_upper[1] + 0.3
    steps = (*plan.steps[:-1], dataclasses.replace(last, q=q))
    return dataclasses.replace(plan, steps=steps)


def test_verify_reports_a_planted_violation(hand, tmp_path, capsys):
    step = len(make_plan(hand).steps) - 1
    planted = rf"step {step}: joint_limit \[{re.escape(hand.joint_names[1])}\]"
    clean = make_plan(hand).save(tmp_path / "plan.json")
    cli.main(["verify", str(clean), "--all"])
    assert not re.search(planted, capsys.readouterr().out)
    path = planted_plan(hand).save(tmp_path / "bad_plan.json")
    assert cli.main(["verify", str(path), "--all"]) == cli.EXIT_FAILED
    out = capsys.readouterr().out
    assert "FAILED" in out
    assert re.search(planted, out), out


def test_verify_unreadable_plan_is_bad_input(tmp_path, capsys):
    path = tmp_path / "garbage.json"
    path.write_text("{not json", encoding="utf-8")
    assert cli.main(["verify", str(path)]) == cli.EXIT_BAD_INPUT
    assert "garbage.json" in _one_error_line(capsys.readouterr().err)
    assert cli.main(["verify", str(tmp_path / "absent.json")]) == cli.EXIT_BAD_INPUT
    assert "absent.json" in _one_error_line(capsys.readouterr().err)


def test_internal_error_exit_3(hand, tmp_path, capsys, monkeypatch):
    import regrasp_casadi.verify as verify_mod

    def boom(*args, **kwargs):
        raise RuntimeError("simulated bug")

    monkeypatch.setattr(verify_mod, "verify", boom)
    path = make_plan(hand).save(tmp_path / "plan.json")
    assert cli.main(["verify", str(path)]) == cli.EXIT_INTERNAL
    line = _one_error_line(capsys.readouterr().err)
    assert "internal error" in line and "simulated bug" in line


def _scene_commands(html: str) -> list[dict]:
    import umsgpack

    blobs = re.findall(r'fetch\("data:application/octet-binary;base64,([A-Za-z0-9+/=]+)"\)', html)
    return [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]


def test_view_html_round_trip(hand, tmp_path, capsys):
    plan = make_plan(hand)
    path = plan.save(tmp_path / "plan.json")
    out = tmp_path / "replay.html"
    assert cli.main(["view", str(path), "--html", str(out)]) == 0
    assert str(out) in capsys.readouterr().out
    html = out.read_text(encoding="utf-8")
    cmds = _scene_commands(html)
    objects = {c["path"] for c in cmds if c["type"] == "set_object"}
    assert "/meshcat/regrasp/object/mesh" in objects
    for link in hand.link_names:
        if link != "palm_link" and not link.endswith("_tip"):
            assert any(p.startswith(f"/meshcat/regrasp/hand/{link}/") for p in objects), link
    goal = "/meshcat/regrasp/object/goal_contacts/"
    goal_markers = {p[len(goal):].split("/")[0] for p in objects if p.startswith(goal)}
    assert goal_markers == set(plan.fingers)   # one marker (of concentric discs) per finger
    (anim,) = [c for c in cmds if c["type"] == "set_animation"]
    # the reloaded plan's object pose at the last step is the animation's last object key
    clip = next(a["clip"] for a in anim["animations"] if a["path"] == "/meshcat/regrasp/object")
    pos = next(t for t in clip["tracks"] if t["name"] == ".position")
    np.testing.assert_allclose(pos["keys"][-1]["value"], plan.steps[-1].T_palm_object[:3, 3], atol=1e-6)


def test_grasps_missing_mesh_is_bad_input(tmp_path, capsys):
    assert cli.main(["grasps", str(tmp_path / "nothing.obj")]) == cli.EXIT_BAD_INPUT
    assert "nothing.obj" in _one_error_line(capsys.readouterr().err)


def test_bench_without_script_is_bad_input(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(cli, "BENCH_SCRIPT", tmp_path / "paper_objects.py")
    assert cli.main(["bench"]) == cli.EXIT_BAD_INPUT
    assert "paper_objects.py" in _one_error_line(capsys.readouterr().err)


def test_bench_passes_its_arguments(tmp_path, capsys, monkeypatch):
    script = tmp_path / "paper_objects.py"
    script.write_text("import sys\nprint('ARGS', sys.argv[1:])\nsys.exit(1 if '--fail' in sys.argv else 0)\n",
                      encoding="utf-8")
    monkeypatch.setattr(cli, "BENCH_SCRIPT", script)
    assert cli.main(["bench", "--objects", "banana", "--n", "2"]) == 0
    assert "ARGS ['--objects', 'banana', '--n', '2']" in capsys.readouterr().out
    assert cli.main(["bench", "--fail"]) == 1
    assert cli.main(["bench", "--", "--help"]) == 0
    assert "ARGS ['--help']" in capsys.readouterr().out


def test_installed_console_script_help():
    exe = shutil.which("regrasp") or str(Path(sys.executable).parent / "regrasp")
    if not Path(exe).exists():
        pytest.skip("the `regrasp` console script is not installed (pip install -e .)")
    proc = subprocess.run([exe, "--help"], capture_output=True, text=True, timeout=60, check=False)
    assert proc.returncode == 0, proc.stderr
    assert "exit codes" in proc.stdout and "demo" in proc.stdout


PROBLEM = Path(__file__).resolve().parents[1] / "problems" / "box_rotate.yaml"


def _plan_from_problem(problem, status: str):
    from regrasp_casadi.plan import Plan, PlanStep

    g0 = problem.grasp0
    m = len(problem.hand.fingers)
    err = np.linalg.norm(g0.contacts_object - problem.grasp_goal.contacts_object, axis=1)
    step = PlanStep(kind="initial", finger=None, q=g0.q, T_palm_object=g0.T_palm_object,
                    contacts_object=g0.contacts_object, contact_error=err, solver_status="", solve_time=0.0)
    return Plan(steps=(step,), goal_contacts_object=problem.grasp_goal.contacts_object,
                goal_T_palm_object=problem.grasp_goal.T_palm_object, fingers=problem.hand.fingers,
                hand_spec=problem.hand.spec(), object_spec=problem.obj.spec, method="svd", status=status,
                status_detail="", iterations=0, iteration_errors=np.full(1, err.mean()),
                timing={"total": 0.0}, options={"max_iters": m})


@pytest.mark.parametrize(("status", "verified", "code"), [
    ("converged", True, 0), ("converged", False, 1), ("iteration_limit", True, 1),
    ("solver_failure", False, 1),
])
def test_plan_exit_code_follows_status_and_verify(status, verified, code, tmp_path, capsys, monkeypatch):
    if not PROBLEM.is_file():
        pytest.skip(f"{PROBLEM} not present")
    import regrasp_casadi.planner as planner_mod
    import regrasp_casadi.verify as verify_mod

    calls = []

    def fake_plan(grasp0, grasp_goal, progress=None, **options):
        calls.append(options)
        from regrasp_casadi.problem import RegraspProblem

        if progress is not None:
            progress(1, options.get("max_iters", 50), 0.004)
        return _plan_from_problem(RegraspProblem.load(PROBLEM), status)

    def fake_verify(plan, hand=None, obj=None, **kw):
        return verify_mod.VerifyReport(ok=verified, violations=(), metrics={"n_steps": len(plan.steps)})

    monkeypatch.setattr(planner_mod, "plan_regrasp", fake_plan)
    monkeypatch.setattr(verify_mod, "verify", fake_verify)
    out = tmp_path / "plan.json"
    argv = ["plan", str(PROBLEM), "--method", "sd", "--max-iters", "7", "--out", str(out),
            "--html", str(tmp_path / "r.html")]
    assert cli.main(argv) == code
    assert calls == [{"method": "sd", "max_iters": 7, "stability": "force_closure"}]
    from regrasp_casadi.plan import Plan

    assert Plan.load(out).status == status
    assert (tmp_path / "r.html").stat().st_size > 0
    text = capsys.readouterr().out
    assert status in text and ("verify: OK" in text) == verified


@pytest.mark.slow
def test_demo_end_to_end(tmp_path, capsys):
    """The real planner on the built-in problem: it converges, verifies, and the exit code says so."""
    from regrasp_casadi.plan import Plan
    from regrasp_casadi.verify import verify

    code = cli.main(["demo", "--out-dir", str(tmp_path), "--no-progress"])
    out = capsys.readouterr().out
    assert code == 0, out
    plan = Plan.load(tmp_path / "plan.json")
    assert plan.status == "converged" and verify(plan).ok
    assert np.max(plan.steps[-1].contact_error) <= plan.options["zeta"]
    assert "(box_rotate)" in out and "verify: OK" in out
    assert "MeshCat.Viewer" in (tmp_path / "replay.html").read_text(encoding="utf-8")
    assert 3 <= len(out.strip().splitlines()) <= 10


@pytest.mark.slow
def test_demo_generates_a_problem_when_the_file_is_missing(tmp_path, capsys, monkeypatch):
    """Without the problem file the demo generates a box regrasp (seed 0) and plans it to convergence."""
    from regrasp_casadi.plan import Plan

    monkeypatch.setattr(cli, "DEMO_PROBLEM", tmp_path / "absent.yaml")
    code = cli.main(["demo", "--out-dir", str(tmp_path / "out"), "--no-progress"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "(box_generated)" in out and "verify: OK" in out
    plan = Plan.load(tmp_path / "out" / "plan.json")
    assert plan.status == "converged"
    assert plan.object_spec["extents"] == [0.06, 0.06, 0.12]
    assert (tmp_path / "out" / "replay.html").is_file()


@pytest.mark.parametrize(("extra", "error"), [
    (["--gravity", "1", "2"], "expected X Y Z"),
    (["--gravity", "up"], "expected a finite number"),
    (["--gravity", "support", "--stability", "none"], "needs --stability gravity"),
])
def test_plan_gravity_bad_input(extra, error, tmp_path, capsys):
    """``--gravity`` takes X Y Z or "support", and only with the gravity certificate; bad input exits 2
    before any planning, naming the option."""
    assert cli.main(["plan", str(PROBLEM), "--out", str(tmp_path / "p.json"), *extra]) == cli.EXIT_BAD_INPUT
    line = _one_error_line(capsys.readouterr().err)
    assert "--gravity" in line and error in line


def _record_plan_calls(monkeypatch, problem) -> list[dict]:
    """Replace the planner by one that records its options and returns `problem`'s one-step plan."""
    import regrasp_casadi.planner as planner_mod

    calls: list[dict] = []

    def fake_plan(grasp0, grasp_goal, progress=None, **options):
        calls.append(options)
        return _plan_from_problem(problem, "converged")

    monkeypatch.setattr(planner_mod, "plan_regrasp", fake_plan)
    return calls


def test_plan_gravity_support_is_the_supporting_direction(tmp_path, capsys, monkeypatch):
    """``--gravity support`` plans with the gravity certificate along `supporting_gravity` of the problem's
    initial grasp (here the box's thumb face normal, reversed, in the palm frame)."""
    from regrasp_casadi.problem import RegraspProblem

    problem = RegraspProblem.load(PROBLEM)
    calls = _record_plan_calls(monkeypatch, problem)
    cli.main(["plan", str(PROBLEM), "--gravity", "support", "--out", str(tmp_path / "p.json")])
    (options,) = calls
    assert options["stability"] == "gravity"
    g0 = problem.grasp0
    thumb = list(problem.hand.fingers).index("thumb")
    n_thumb = problem.obj.surface_normals(g0.contacts_object[thumb:thumb + 1])[0]
    g_object = np.asarray(g0.T_palm_object)[:3, :3].T @ options["gravity_palm"]
    np.testing.assert_allclose(g_object, -9.81 * n_thumb, atol=1e-9)
    assert np.isclose(abs(n_thumb[0]), 1.0)  # the box's ±x face: the fingers' face is opposite (problem file)


@pytest.mark.parametrize(("extra", "stability", "gravity"), [
    ([], "gravity", (0.0, -9.81, 0.0)),                                    # the file's gravity
    (["--gravity", "1", "2", "3"], "gravity", (1.0, 2.0, 3.0)),            # the flag wins
    (["--stability", "force_closure"], "force_closure", None),             # an explicit certificate
])
def test_plan_takes_the_problem_files_gravity(extra, stability, gravity, tmp_path, monkeypatch):
    """A problem file's `gravity` makes `regrasp plan` certify every step for it, unless ``--gravity``
    gives another or ``--stability`` asks for another certificate."""
    import yaml

    from regrasp_casadi.problem import RegraspProblem

    doc = yaml.safe_load(PROBLEM.read_text())
    doc["gravity"] = [0.0, -9.81, 0.0]
    path = tmp_path / "with_gravity.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    calls = _record_plan_calls(monkeypatch, RegraspProblem.load(path))
    cli.main(["plan", str(path), "--out", str(tmp_path / "p.json"), *extra])
    (options,) = calls
    assert options["stability"] == stability and options.get("gravity_palm") == gravity


def test_plan_restarts_flag_reaches_the_planner_and_bad_values_exit_2(tmp_path, capsys, monkeypatch):
    """``--restarts N`` is the planner's `restarts`; without it the planner's default holds (no key);
    a negative count is bad input (exit 2) naming the flag, before any planning."""
    from regrasp_casadi.problem import RegraspProblem

    calls = _record_plan_calls(monkeypatch, RegraspProblem.load(PROBLEM))
    cli.main(["plan", str(PROBLEM), "--restarts", "0", "--out", str(tmp_path / "p.json"), "--no-progress"])
    cli.main(["plan", str(PROBLEM), "--out", str(tmp_path / "q.json"), "--no-progress"])
    assert calls[0]["restarts"] == 0 and "restarts" not in calls[1]
    capsys.readouterr()
    assert cli.main(["plan", str(PROBLEM), "--restarts", "-1"]) == cli.EXIT_BAD_INPUT
    assert "--restarts" in _one_error_line(capsys.readouterr().err)
    assert len(calls) == 2


def test_plan_says_a_plan_was_restarted(tmp_path, capsys):
    """The real planner on the box problem cut short (one iteration): the first plan and its one restart
    both stop at the limit; the summary says so, and the plan file keeps both plans' count."""
    from regrasp_casadi.plan import Plan

    out = tmp_path / "p.json"
    code = cli.main(["plan", str(PROBLEM), "--stability", "none", "--max-iters", "1", "--restarts", "1",
                     "--out", str(out), "--no-progress"])
    text = capsys.readouterr().out
    assert code == cli.EXIT_FAILED
    assert "1 restart, none converged: the first plan is kept (2 iterations in all)" in text
    plan = Plan.load(out)
    assert plan.options["attempts"] == 2 and plan.options["iterations_all"] == 2


def test_the_restart_line_names_what_the_restarts_did():
    """A plan made once has no line; a converged restart is named; a Ctrl-C during a restart says so."""
    from types import SimpleNamespace

    from regrasp_casadi.cli_plan import restart_line

    def plan(status, **options):
        return SimpleNamespace(status=status, iterations=4, options=options)

    assert restart_line(plan("converged")) is None
    assert restart_line(plan("converged", attempts=2, restart="gait reversed", iterations_all=9)) == (
        "restarted: the first plan did not converge; this is restart 1 (gait reversed), 2 plans and 9 "
        "iterations in all")
    assert restart_line(plan("interrupted", attempts=3, restart="", iterations_all=7)) == (
        "interrupted during restart 2: the first plan is kept (7 iterations in all)")
