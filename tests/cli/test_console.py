"""The commands' console: whole tables in logs, written paths printed whole."""

from __future__ import annotations

from pathlib import Path

from rich.table import Table

from sensorgym.cli.console import LOG_WIDTH, make_console, print_path, print_written


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
