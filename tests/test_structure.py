"""The package's structure rules that hold today, checked with scripts/structure.py's own
functions: no module uses another module's private names, no import cycle between modules.
(Its size limits are checked by ``python scripts/structure.py --check`` in .ci/run.)"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def structure():
    """scripts/structure.py, loaded as a module."""
    name = "camvlp_scripts_structure"
    spec = importlib.util.spec_from_file_location(name, REPO / "scripts" / "structure.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # the dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def write_package(root: Path, files: dict[str, str]) -> Path:
    """A package ``camvlp`` of ``files`` (path under the package -> source) in ``root``;
    every folder gets an ``__init__.py``. Returns ``root``, the folder that holds it."""
    for name, text in files.items():
        path = root / "camvlp" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    for folder in [root / "camvlp", *(root / "camvlp").rglob("*")]:
        if folder.is_dir() and not (folder / "__init__.py").exists():
            (folder / "__init__.py").write_text("", encoding="utf-8")
    return root


#: A module with a private and a public name, and a package with a private module.
LIBRARY = {
    "a.py": "def _helper():\n    return 1\n\n\ndef helper():\n    return _helper()\n",
    "cli/_app.py": "APP = 1\n",
    "cli/run.py": "from camvlp.cli import _app\nfrom camvlp.cli._app import APP\n",
    "cli/sub/deep.py": "from camvlp.cli._app import APP\n",
}


def test_the_package_imports_no_private_name_of_another_module(structure):
    assert structure.private_uses() == []


def test_the_package_has_no_import_cycle(structure):
    assert structure.import_cycles() == []


def test_public_names_and_a_private_module_within_its_package_are_allowed(structure, tmp_path):
    root = write_package(
        tmp_path, {**LIBRARY, "b.py": "from camvlp.a import helper\nimport camvlp.a as m\nm.x\n"}
    )
    assert structure.private_uses(root) == []


@pytest.mark.parametrize(
    ("source", "found"),
    [
        ("from camvlp.a import _helper\n", "from camvlp.a import _helper"),
        ("from .a import _helper\n", "from camvlp.a import _helper"),
        ("import camvlp.a as m\n\n\ndef f():\n    return m._helper()\n", "m._helper"),
        ("from camvlp import a\n\na._helper()\n", "a._helper"),
        ("import camvlp.a\n\ncamvlp.a._helper()\n", "camvlp.a._helper"),
        ("from camvlp.cli import _app\n", "from camvlp.cli import _app"),
        ("from camvlp.cli._app import APP\n", "from camvlp.cli._app import APP"),
        ("import camvlp.cli._app\n", "import camvlp.cli._app"),
    ],
)
def test_an_import_of_a_private_name_is_found(structure, tmp_path, source, found):
    root = write_package(tmp_path, {**LIBRARY, "b.py": source})
    assert [use.partition(": ")[2] for use in structure.private_uses(root)] == [found]
    assert structure.private_uses(root)[0].startswith(str(root / "camvlp" / "b.py"))


def test_an_import_cycle_is_found(structure, tmp_path):
    root = write_package(
        tmp_path,
        {"a.py": "import camvlp.b\n", "b.py": "def f():\n    from camvlp import c\n", "c.py": ""},
    )
    assert structure.import_cycles(root) == []
    (root / "camvlp" / "c.py").write_text("from camvlp.a import x\n", encoding="utf-8")
    assert structure.import_cycles(root) == [["camvlp.a", "camvlp.b", "camvlp.c"]]
