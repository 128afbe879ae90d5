"""A real host: the Blender add-on (normalfit-py/blender/), installed from
its zip and enabled as a user does, makes normal maps of image datablocks
through the package; the pixels must be the command line's float EXR, bit
for bit, read back by Blender's own EXR reader.

Runs where Blender is installed (Debian: ``apt-get install blender
python3-numpy``; CI installs both) and is skipped, with that reason,
where it is not. Each run gets its own Blender user folders, so nothing
is installed into the machine's.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import normalfit
from conftest import ROOT, run_cli

BLENDER = shutil.which("blender")
DRIVER = Path(__file__).with_name("blender_driver.py")
BUILD_ZIP = ROOT / "normalfit-py" / "blender" / "build_zip.py"

pytestmark = pytest.mark.skipif(BLENDER is None, reason="Blender is not installed (apt-get install blender python3-numpy)")


@pytest.fixture(scope="module")
def addon_zip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("addon") / "normalfit_blender.zip"
    subprocess.run([sys.executable, str(BUILD_ZIP), str(out)], check=True, capture_output=True)
    return out


@pytest.fixture(scope="module")
def package_only(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder holding only the installed normalfit package, for Blender's
    own Python (its NumPy stays Blender's)."""
    folder = tmp_path_factory.mktemp("blender-path")
    (folder / "normalfit").symlink_to(Path(normalfit.__file__).parent, target_is_directory=True)
    return folder


def run_blender(addon_zip: Path, tmp_path: Path, job: dict[str, object], pythonpath: Path | None) -> dict[str, np.ndarray]:
    """Runs the driver on `job` in a Blender with its own user folders; the
    driver's results."""
    assert BLENDER is not None
    out = tmp_path / "result.npz"
    job_path = tmp_path / "job.json"
    job_path.write_text(json.dumps({**job, "out": str(out)}))
    env = {
        **os.environ,
        "BLENDER_USER_SCRIPTS": str(tmp_path / "user-scripts"),
        "BLENDER_USER_CONFIG": str(tmp_path / "user-config"),
    }
    env.pop("PYTHONPATH", None)
    if pythonpath is not None:
        env["PYTHONPATH"] = str(pythonpath)
    command = [BLENDER, "-b", "--factory-startup", "--python-use-system-env", "--python", str(DRIVER), "--"]
    done = subprocess.run(
        [*command, str(addon_zip), str(job_path)], capture_output=True, text=True, timeout=600, env=env
    )
    assert done.returncode == 0, f"blender exit {done.returncode}:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    with np.load(out) as data:
        return {k: data[k] for k in data.files}


CASES = [
    # sample, the operator's keywords, the CLI's options for the same map
    ("rock.png", {"patch": 5, "scale": 4.0}, ["-n", "5", "-s", "4"]),
    ("terrain.png", {"scale": 8.0, "border": "clamp"}, ["-s", "8", "--border", "clamp"]),
    (
        "bricks.png",
        {"patch": 7, "border": "auto", "convention": "directx", "fit": "vertical", "invert": True},
        ["-n", "7", "--border", "auto", "--convention", "directx", "--fit", "vertical", "--invert"],
    ),
    # A colour image: the heights are its luma, as the CLI takes them.
    ("rock_normal.png", {"patch": 3, "scale": 2.0}, ["-n", "3", "-s", "2"]),
]


@pytest.mark.parametrize(("sample", "options", "cli_options"), CASES, ids=[c[0] for c in CASES])
def test_the_operator_makes_the_clis_pixels(
    sample: str,
    options: dict[str, object],
    cli_options: list[str],
    addon_zip: Path,
    package_only: Path,
    cli: Path,
    tmp_path: Path,
) -> None:
    source = ROOT / "samples" / sample
    exr = tmp_path / "cli.exr"
    run_cli(cli, "convert", source, "-o", exr, "--bits", "32", "--quiet", *cli_options)
    got = run_blender(addon_zip, tmp_path, {"source": str(source), "options": options, "cli": str(exr)}, package_only)
    made, want = got["made"], got["cli"]
    assert str(got["colorspace"]) == "Non-Color" and bool(got["is_float"])
    assert made.dtype == want.dtype == np.float32 and made.shape == want.shape == (512, 512, 3)
    differ = np.count_nonzero(np.any(made.view(np.uint32) != want.view(np.uint32), axis=-1))
    assert differ == 0, f"{differ} of {512 * 512} texels differ from the CLI's EXR"
    # Not a map of zeros: the sample has relief in every direction.
    assert made[:, :, 0].std() > 0.01 and made[:, :, 1].std() > 0.01


CURVATURE_CASES = [
    ("rock.png", {"patch": 5, "scale": 4.0}, ["-n", "5", "-s", "4"]),
    ("terrain.png", {"patch": 9, "scale": 8.0, "border": "clamp"}, ["-n", "9", "-s", "8", "--border", "clamp"]),
]


@pytest.mark.parametrize(("sample", "options", "cli_options"), CURVATURE_CASES, ids=[c[0] for c in CURVATURE_CASES])
def test_the_curvature_operator_makes_the_clis_pixels(
    sample: str,
    options: dict[str, object],
    cli_options: list[str],
    addon_zip: Path,
    package_only: Path,
    cli: Path,
    tmp_path: Path,
) -> None:
    source = ROOT / "samples" / sample
    exr = tmp_path / "cli.exr"
    run_cli(cli, "convert", source, "-o", exr, "--product", "curvature", "--quiet", *cli_options)
    job = {"source": str(source), "operator": "curvature", "options": options, "cli": str(exr)}
    got = run_blender(addon_zip, tmp_path, job, package_only)
    made, want = got["made"], got["cli"]
    assert str(got["colorspace"]) == "Non-Color" and bool(got["is_float"])
    assert made.dtype == want.dtype == np.float32 and made.shape == want.shape == (512, 512, 3)
    # One value a texel, in R, G and B alike; the CLI's EXR holds it in Y.
    assert np.array_equal(made[:, :, 0], made[:, :, 1]) and np.array_equal(made[:, :, 0], made[:, :, 2])
    differ = np.count_nonzero(made[:, :, 0].view(np.uint32) != want[:, :, 0].view(np.uint32))
    assert differ == 0, f"{differ} of {512 * 512} texels differ from the CLI's EXR"
    # Convex and concave texels both: the sample has relief.
    assert (made[:, :, 0] > 0).any() and (made[:, :, 0] < 0).any()


def test_the_operator_wires_the_map_into_the_material(addon_zip: Path, package_only: Path, tmp_path: Path) -> None:
    job = {"source": str(ROOT / "samples" / "rock.png"), "options": {"scale": 4.0, "wire": True}, "wire": True}
    got = run_blender(addon_zip, tmp_path, job, package_only)
    links = set(got["links"].tolist())
    assert "TEX_IMAGE.Color>NORMAL_MAP.Color" in links, links
    assert "NORMAL_MAP.Normal>BSDF_PRINCIPLED.Normal" in links, links
    assert got["textures"].tolist() == ["heights_normal"]


def test_a_refusal_is_the_operators_one_line_report(addon_zip: Path, package_only: Path, tmp_path: Path) -> None:
    for options, says in [({"patch": 4}, "patch"), ({"image": "absent"}, "absent")]:
        job = {"source": str(ROOT / "samples" / "rock.png"), "options": options}
        if "image" in options:
            job["image"] = options.pop("image")
        got = run_blender(addon_zip, tmp_path, job, package_only)
        error = str(got["error"])
        assert says in error and "made" not in got, error
        assert len(error.strip().splitlines()) == 1, error


def test_without_the_package_the_operator_says_how_to_install_it(addon_zip: Path, tmp_path: Path) -> None:
    job = {"source": str(ROOT / "samples" / "rock.png"), "options": {}}
    got = run_blender(addon_zip, tmp_path, job, None)
    assert "normalfit package is not installed" in str(got["error"]), got["error"]


WHEEL = os.environ.get("NORMALFIT_WHEEL")


@pytest.mark.skipif(WHEEL is None, reason="NORMALFIT_WHEEL (the built wheel, .ci/test sets it) is not set")
def test_the_preferences_install_the_wheel_into_blenders_python(addon_zip: Path, tmp_path: Path) -> None:
    assert WHEEL is not None
    job = {"source": str(ROOT / "samples" / "rock.png"), "options": {"patch": 5}, "install": WHEEL}
    got = run_blender(addon_zip, tmp_path, job, None)
    installed = Path(str(got["installed"]))
    assert installed.is_relative_to(tmp_path / "user-scripts"), installed
    assert Path(str(got["imported"])).is_relative_to(installed)
    assert "made" in got and got["made"].shape == (512, 512, 3)


@pytest.mark.skipif(WHEEL is None, reason="NORMALFIT_WHEEL (the built wheel, .ci/test sets it) is not set")
def test_a_wheel_unpacks_without_pip(addon_zip: Path, tmp_path: Path) -> None:
    """The way in for a distribution's Python that has no pip."""
    assert WHEEL is not None
    into = tmp_path / "modules"
    into.mkdir()
    (into / "normalfit").mkdir()
    (into / "normalfit" / "stale.py").write_text("")
    job = {"source": str(ROOT / "samples" / "rock.png"), "options": {"patch": 5}, "unpack": WHEEL, "into": str(into)}
    got = run_blender(addon_zip, tmp_path, job, None)
    assert Path(str(got["imported"])).is_relative_to(into)
    assert not (into / "normalfit" / "stale.py").exists()
    assert "made" in got and got["made"].shape == (512, 512, 3)
