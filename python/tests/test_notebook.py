"""The example notebook runs top to bottom (nbclient), so it cannot rot."""

from __future__ import annotations

import pytest

from conftest import REPO

NOTEBOOK = REPO / "examples" / "python" / "hidden_effect.ipynb"


def test_hidden_effect_notebook_runs():
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    nb = nbformat.read(NOTEBOOK, as_version=4)
    client = nbclient.NotebookClient(
        nb, timeout=600, kernel_name="python3",
        resources={"metadata": {"path": str(NOTEBOOK.parent)}},
    )
    client.execute()
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.get("output_type") == "error"]
    html = [o for o in outputs if "text/html" in o.get("data", {})]
    assert any("<svg" in o["data"]["text/html"] for o in html), "the diagnosis shows its figure"
    text = "".join(o.get("text", "") for o in outputs)
    assert "bias_model.c" in text and "error std:" in text
