"""README's layout table matches the tree: every layer folder has a row that names each of
its modules and subpackages, and the rows follow the import order the layering test checks."""

from __future__ import annotations

import re
from pathlib import Path

from test_exports import LAYERS

ROOT = Path(__file__).resolve().parents[1]


def _rows() -> dict[str, str]:
    text = (ROOT / "README.md").read_text()
    table = text[text.index("## Layout") :]
    rows = {}
    for line in table.splitlines():
        m = re.match(r"\| `(\w+)/` \| `geosyn\.(\w+)` \|(.*)\|$", line)
        if m:
            assert m.group(1) == m.group(2), line
            rows[m.group(1)] = m.group(3)
    return rows


def test_layout_table_names_every_layer_in_import_order() -> None:
    assert list(_rows()) == LAYERS


def test_layout_table_names_every_module() -> None:
    missing = []
    for layer, text in _rows().items():
        named = set(re.findall(r"`([\w/]+)`", text)) | set(re.findall(r"(\w+)/", text))
        named |= {n.rstrip("/") for n in named}
        for path in sorted((ROOT / "geosyn" / layer).iterdir()):
            if path.name.startswith(("_", ".")) or path.name == "configs":
                continue
            if path.suffix == ".py" and path.stem not in named:
                missing.append(f"{layer}/{path.name}")
            if path.is_dir() and (path / "__init__.py").exists() and path.name not in named:
                missing.append(f"{layer}/{path.name}/")
    assert not missing, f"README layout table does not name: {missing}"
