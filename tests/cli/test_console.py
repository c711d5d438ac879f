"""The commands' console: whole tables in logs, written paths printed whole."""

from __future__ import annotations

from pathlib import Path

from rich.table import Table

from sensorgym.cli.console import LOG_WIDTH, Steps, make_console, print_path, print_written


def test_a_long_path_with_brackets_prints_whole_on_one_line(capsys):
    path = Path("/tmp") / ("deep_folder_" * 20) / "run[seed=0]" / "sweep.png"
    assert len(str(path)) > LOG_WIDTH
    console = make_console()  # stdout captured: not a terminal
    print_written(console, [path, Path("b.json")])
    print_path(console, "saved ", path)
    lines = capsys.readouterr().out.splitlines()
    assert lines == ["wrote:", f"  {path}", "  b.json", f"saved {path}"]


def test_tables_in_a_log_take_the_log_width(capsys):
    console = make_console()
    assert console.width == LOG_WIDTH
    table = Table()
    table.add_column("a")
    table.add_row("x" * 120)
    console.print(table)
    assert "x" * 120 in capsys.readouterr().out


def test_steps_print_a_line_per_step_in_a_log_and_a_bar_on_a_terminal():
    import io

    from rich.console import Console

    log = io.StringIO()
    with Steps(Console(file=log, force_terminal=False, width=120), "env", 3) as steps:
        for name in ("rule-a", "rule-b", "policy [x]"):
            steps.start(name)
    lines = log.getvalue().splitlines()
    assert [line.split(" (")[0] for line in lines] == [
        "env: rule-a",
        "env: rule-b",
        "env: policy [x]",
    ]
    assert lines[-1].startswith("env: policy [x] (3/3, ") and lines[-1].endswith(" s)")
    assert steps.done == 3
    tty = io.StringIO()
    with Steps(Console(file=tty, force_terminal=True, width=120), "env", 2) as steps:
        steps.start("rule-a")
        steps.start("rule-b")
    assert steps.done == 2 and "rule-a (1/2" not in tty.getvalue()  # a bar, not lines
