"""The package's layout: old module paths still import, the locator stays light."""

import subprocess
import sys
import warnings

import pytest


@pytest.mark.parametrize(
    ("old", "new"),
    [
        ("camvlp.study", "camvlp.analysis.study"),
        ("camvlp.simulate", "camvlp.sim.render"),
        ("camvlp.pnp", "camvlp.geometry.pnp"),
        ("camvlp.camera", "camvlp.model.camera"),
    ],
)
def test_old_module_paths_import_with_a_warning(old, new):
    code = (
        "import warnings, importlib\n"
        "with warnings.catch_warnings(record=True) as w:\n"
        "    warnings.simplefilter('always')\n"
        f"    old = importlib.import_module({old!r})\n"
        f"new = importlib.import_module({new!r})\n"
        "assert old is new, (old, new)\n"
        "assert any(issubclass(x.category, DeprecationWarning) for x in w), w\n"
        f"assert {new!r} in str(w[0].message)\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_locate_function_survives_importing_its_module_path():
    code = (
        "import camvlp, camvlp.locate\n"
        "from camvlp.locate import LocateResult\n"
        "assert callable(camvlp.locate) and camvlp.locate.__name__ == 'locate'\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_locating_does_not_import_matplotlib():
    code = "import sys, camvlp.locate\nassert 'matplotlib' not in sys.modules\n"
    subprocess.run([sys.executable, "-c", code], check=True)


def test_no_warning_from_the_new_paths():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        import camvlp.analysis.study
        import camvlp.pipeline.locate  # noqa: F401
