"""The ``sensorgym`` command: subcommands run and print real numbers."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from sensorgym.cli.main import COMMANDS, DEFAULT_JOB, build_parser, main
from sensorgym.cli.reproduce import available


def test_every_subcommand_has_help(capsys):
    parser = build_parser()
    for name in COMMANDS:
        with pytest.raises(SystemExit) as exc:
            parser.parse_args([name, "--help"])
        assert exc.value.code == 0
        assert "usage: sensorgym" in capsys.readouterr().out
    assert DEFAULT_JOB[0] in COMMANDS


def test_no_arguments_prints_the_help_and_names_the_main_job(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main([]) == 0
    printed = capsys.readouterr().out
    assert "usage: sensorgym" in printed and "The main job: sensorgym benchmark" in printed
    assert not any(tmp_path.iterdir())  # nothing ran
    # run.sh's default is the main job
    run_sh = (Path(__file__).resolve().parents[2] / "scripts" / "run.sh").read_text()
    assert f"set -- {' '.join(DEFAULT_JOB)}" in run_sh


def test_the_main_job_is_the_benchmark_of_every_env(tmp_path, monkeypatch, capsys):
    from PIL import Image

    from sensorgym.train.benchmark import registered_envs
    from sensorgym.train.shipped import shipped_policies

    assert DEFAULT_JOB == ["benchmark"]
    # the main job exactly, on tiny settings (the defaults write under ./results)
    monkeypatch.chdir(tmp_path)
    assert main([*DEFAULT_JOB, "--episodes", "2", "--n-envs", "2"]) == 0
    printed = capsys.readouterr().out
    out = tmp_path / "results" / "benchmark"
    summary = json.loads((out / "benchmark.json").read_text())
    envs = registered_envs()
    assert len(envs) >= 3 and set(summary["scores"]) == set(envs)
    for env_id in envs:
        assert env_id in printed
        per_env = json.loads((out / f"{env_id.replace('/', '__')}.json").read_text())
        assert per_env["results"] == summary["scores"][env_id]
        assert per_env["settings"]["seed"] == 10_000
        for run in shipped_policies(env_id):  # every shipped policy is scored
            assert f"shipped:{run}" in per_env["results"]
        for r in per_env["results"].values():
            assert r["episodes"] == 2 and r["ci95"] >= 0.0
        for d in per_env["paired"].values():  # the robust view beside the mean
            assert d["better"] + d["worse"] <= 2 and len(d["iqm_ci95"]) == 2
    assert shipped_policies("sensorgym/StereoPlacement-v0")  # one is shipped at least
    with Image.open(out / "benchmark.png") as png:
        assert png.format == "PNG" and png.size[1] > png.size[0] / 2
    assert "benchmark.png" in printed and "95 % interval" in printed
    assert "paired IQM" in printed and "better/worse" in printed


def test_rescoring_one_env_keeps_the_others_in_the_summary(tmp_path):
    """``--env`` rewrites its env's entry of ``benchmark.json`` and keeps the others' when the
    file was written with the same episodes, batch and seed, in the registry's order; with
    other settings it starts afresh (a summary never mixes settings)."""
    from sensorgym.train.benchmark import registered_envs

    env_id, kept_id = "sensorgym/StereoPlacement-v0", "sensorgym/BearingsManeuver-v0"
    settings = {"episodes": 2, "n_envs": 2, "seed": 10_000}
    summary = tmp_path / "benchmark.json"
    other = {"some-rule": {"mean": 1.0}}
    for kept_settings, kept in ((settings, True), ({**settings, "seed": 7}, False)):
        doc = {"settings": kept_settings, "scores": {kept_id: other, env_id: {}}}
        summary.write_text(json.dumps(doc))
        argv = ["benchmark", "--env", env_id, "--episodes", "2", "--n-envs", "2",
                "--no-shipped", "--no-chart", "--out", str(tmp_path)]  # fmt: skip
        assert main(argv) == 0
        written = json.loads(summary.read_text())
        assert written["settings"] == settings
        per_env = json.loads((tmp_path / f"{env_id.replace('/', '__')}.json").read_text())
        assert written["scores"][env_id] == per_env["results"] != {}
        assert (kept_id in written["scores"]) is kept
        assert list(written["scores"]) == [e for e in registered_envs() if e in written["scores"]]


def test_version(capsys):
    with pytest.raises(SystemExit):
        main(["--version"])
    assert capsys.readouterr().out.startswith("sensorgym ")


def test_triangulate_demo_matches_closed_forms(tmp_path, capsys):
    out = tmp_path / "rows.json"
    assert (
        main(
            [
                "triangulate-demo",
                "--runs",
                "4000",
                "--gammas",
                "30",
                "90",
                "150",
                "--json",
                str(out),
            ]
        )
        == 0
    )
    printed = capsys.readouterr().out
    assert "iid formula" in printed and "30" in printed
    rows = json.loads(out.read_text())
    assert [r["gamma_deg"] for r in rows] == [30, 90, 150]
    for r in rows:
        assert r["iid_monte_carlo"] == pytest.approx(r["iid_predicted"], rel=0.06)
        assert r["angle_monte_carlo"] == pytest.approx(r["angle_predicted"], rel=0.06)
        assert r["position_ml_rms"] == pytest.approx(r["position_crlb_rms"], rel=0.06)
    # orthogonal lines of sight are the most accurate geometry under both models
    assert rows[1]["iid_predicted"] < rows[0]["iid_predicted"]
    assert rows[1]["angle_predicted"] < rows[2]["angle_predicted"]


def test_reproductions_are_discovered_with_their_interface():
    for name, module_name in available().items():
        module = __import__(module_name, fromlist=["run"])
        assert isinstance(module.HELP, str) and module.HELP, name
        assert callable(module.add_arguments) and callable(module.run), name


def test_render_writes_an_animated_episode(tmp_path, capsys):
    from PIL import Image

    out = tmp_path / "episode.gif"
    args = ["--rule", "paper002", "--every", "10", "--out", str(out)]
    assert main(["render", *args]) == 0
    with Image.open(out) as gif:
        assert gif.n_frames == 4  # the reset frame, steps 10 and 20, the last step (30)
        assert gif.size == (480, 528)  # the legend below the axes
    assert "return" in capsys.readouterr().out
    with pytest.raises(SystemExit, match="rule"):
        main(["render", "--rule", "nonsense", "--out", str(out)])


def test_record_plays_several_episodes_into_one_video(tmp_path, capsys):
    import imageio.v2 as imageio

    out = tmp_path / "episodes.mp4"
    args = ["--rule", "paper002", "--episodes", "2", "--every", "10", "--out", str(out)]
    assert main(["record", *args]) == 0  # rl-baselines3-zoo's name for `render`
    printed = capsys.readouterr().out
    returns = [line for line in printed.splitlines() if ": return " in line]
    assert [line.split(", ")[-1].split(":")[0] for line in returns] == ["episode 1", "episode 2"]
    assert "mean return" in printed
    with imageio.get_reader(out) as video:
        assert video.count_frames() == 8  # each episode: reset, steps 10 and 20, the last (30)
        assert video.get_meta_data()["size"] == (480, 528)
    # the same seed plays the same episodes
    assert main(["render", *args[:-1], str(tmp_path / "again.gif")]) == 0
    assert [line for line in capsys.readouterr().out.splitlines() if ": return " in line] == returns


def test_record_falls_back_to_a_gif_without_a_video_writer(tmp_path, capsys, monkeypatch):
    from PIL import Image

    from sensorgym.cli import render

    monkeypatch.setattr(render, "video_writer_missing", lambda: "imageio_ffmpeg not installed")
    out = tmp_path / "episode.mp4"
    assert main(["enjoy", "--rule", "paper002", "--every", "15", "--out", str(out)]) == 0
    assert "no MP4" in capsys.readouterr().out and not out.exists()
    with Image.open(out.with_suffix(".gif")) as gif:
        assert gif.n_frames == 3


def test_enjoy_plays_a_shipped_policy(tmp_path, capsys):
    out = tmp_path / "last.png"
    argv = ["enjoy", "--model", "ppo_seed0", "--episodes", "2", "--out", str(out)]
    assert main(argv) == 0
    assert out.is_file() and capsys.readouterr().out.count(": return ") == 2
