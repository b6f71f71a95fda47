"""examples/notebook.ipynb runs as stored, in a fresh kernel, and shows what it says."""

from __future__ import annotations

import base64
import re
from pathlib import Path
from typing import Any

import nbformat
import pytest
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parent.parent
NOTEBOOK = ROOT / "examples" / "notebook.ipynb"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def test_the_notebook_is_stored_without_outputs() -> None:
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    nbformat.validate(notebook)
    code = [cell for cell in notebook.cells if cell.cell_type == "code"]
    assert code and all(not c.outputs and c.execution_count is None for c in code)


@pytest.fixture(scope="module")
def executed(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """The notebook, executed fresh (in a scratch directory, so nothing lands in examples/)."""
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    workdir = tmp_path_factory.mktemp("notebook")
    client = NotebookClient(
        notebook,
        timeout=60,
        startup_timeout=60,
        kernel_name="python3",
        resources={"metadata": {"path": str(workdir)}},
    )
    client.execute()
    return notebook


def outputs_of(notebook: Any, source_part: str) -> list[Any]:
    """The outputs of the one code cell whose source contains ``source_part``."""
    (cell,) = [c for c in notebook.cells if c.cell_type == "code" and source_part in c.source]
    return list(cell.outputs)


def text_of(outputs: list[Any], kind: str = "text/plain") -> str:
    """Everything printed and every ``kind`` result, joined."""
    parts = []
    for out in outputs:
        if out.output_type == "stream":
            parts.append(out.text)
        elif out.output_type in ("execute_result", "display_data") and kind in out.data:
            parts.append(out.data[kind])
    return "".join(parts)


def found(pattern: str, text: str) -> tuple[str, ...]:
    """The groups of ``pattern``'s first match in ``text`` (which must have one)."""
    match = re.search(pattern, text)
    assert match, f"{pattern!r} not in {text!r}"
    return match.groups()


@pytest.mark.timeout(180)
def test_the_notebook_shows_tables_recordings_and_plots(executed: Any) -> None:
    # A status object as an HTML table.
    status = text_of(outputs_of(executed, "drive.status()"), "text/html")
    assert "<caption" in status and "<tr><td>state</td><td>DriveState.STOPPED</td></tr>" in status

    # The spin-up recording: its summary, its HTML table, the drive reaching its setpoint.
    spin = outputs_of(executed, "spin = drive.record(")
    assert text_of(spin).startswith("<Recording Drive unit 1: ")
    assert '<th style="text-align: right">speed</th>' in text_of(spin, "text/html")
    printed = text_of(outputs_of(executed, "print(spin)"))
    assert "final speed 1500 rpm" in printed and "PeriodStats(mean=" in printed
    count, missed = map(int, found(r"(\d+) samples every 0.05 s .*, (\d+) missed", printed))
    assert count + missed == 40  # 2 s at 50 ms

    described = text_of(outputs_of(executed, "spin.to_pandas().describe()"))
    assert described.split()[:3] == ["speed", "output_frequency", "output_current"]
    assert found(r"count\s+(\d+)\.0+\s", described) == (str(count),)

    # The controller heating toward its new setpoint.
    heat = text_of(outputs_of(executed, "heat = j2.record("))
    first, last = map(float, found(r"PV from (\S+) to (\S+)", heat))
    assert last > first + 10
    csv_text = text_of(outputs_of(executed, "heat.to_csv()"))
    assert csv_text.startswith("time,pv,sv,mv\n") and ",200.0," in csv_text

    # Two plots, as real PNG images.
    images = [
        base64.b64decode(out.data["image/png"])
        for cell in executed.cells
        if cell.cell_type == "code"
        for out in cell.outputs
        if out.output_type == "display_data" and "image/png" in out.data
    ]
    assert len(images) == 2 and all(image.startswith(PNG_SIGNATURE) for image in images)
