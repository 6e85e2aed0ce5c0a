"""The package's layout: ``import camvlp`` stays light, its public names load on first use."""

import json
import subprocess
import sys

import pytest

import camvlp

#: What ``import camvlp`` alone must not load: the stages, the simulator, the analyses, the
#: plots, the service, the command line, and the heavy libraries they use.
HEAVY = (
    "camvlp.pipeline",
    "camvlp.sim",
    "camvlp.analysis",
    "camvlp.viz",
    "camvlp.service",
    "camvlp.cli",
    "cv2",
    "scipy",
    "matplotlib",
    "fastapi",
    "sqlalchemy",
)


def _modules_after(code: str) -> list[str]:
    """The modules loaded by ``code`` in a fresh interpreter."""
    out = subprocess.run(
        [sys.executable, "-c", f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"],
        check=True,
        capture_output=True,
        text=True,
    )
    return json.loads(out.stdout.splitlines()[-1])


def test_importing_camvlp_loads_none_of_the_heavy_parts():
    loaded = _modules_after("import camvlp")
    heavy = [m for m in loaded if any(m == h or m.startswith(h + ".") for h in HEAVY)]
    assert heavy == []
    assert [m for m in loaded if m.startswith("camvlp")] == ["camvlp"]


def test_a_public_name_loads_its_module_on_first_use():
    loaded = _modules_after("import camvlp\ncamvlp.Camera")
    assert "camvlp.model.camera" in loaded
    assert "camvlp.pipeline.locate" not in loaded and "camvlp.sim.render" not in loaded


@pytest.mark.parametrize("name", camvlp.__all__)
def test_every_public_name_resolves_from_its_module(name):
    value = getattr(camvlp, name)
    assert value is not None
    assert name in dir(camvlp)


def test_an_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no_such_name"):
        _ = camvlp.no_such_name


def test_locate_is_the_function():
    from camvlp import locate

    assert callable(camvlp.locate) and camvlp.locate is locate and locate.__name__ == "locate"


def test_locating_does_not_import_matplotlib():
    loaded = _modules_after("import camvlp.pipeline.locate")
    assert "matplotlib" not in loaded
