"""The example notebook runs from start to end in a fresh kernel of this environment.

``examples/holoview_in_xarray.ipynb`` simulates, processes, opens the results in
xarray, plots with matplotlib and exports; executed here with nbclient, in a
temporary folder, each cell's errors failing the test.
"""

from __future__ import annotations

from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

NOTEBOOK = Path(__file__).resolve().parents[1] / "examples" / "holoview_in_xarray.ipynb"


@pytest.mark.slow
def test_example_notebook_runs(tmp_path: Path) -> None:
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    client = NotebookClient(
        notebook,
        timeout=120,
        kernel_name="python3",
        resources={"metadata": {"path": str(tmp_path)}},
    )
    client.execute()
    outputs = [o for cell in notebook.cells if cell.cell_type == "code" for o in cell.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    images = [o for o in outputs if "image/png" in o.get("data", {})]
    assert len(images) >= 4  # hologram, map and centre series, trends, spectrum
    text = "".join(o.get("text", "") for o in outputs if o.output_type == "stream")
    assert "('time', 'y', 'x') m m" in text
    assert (tmp_path / "holoview-example" / "run.nc").is_file()
