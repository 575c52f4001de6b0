"""The built wheel carries the kernels: install it in a fresh venv and run `clsonar echoes`."""

import shutil
import site
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_wheel_installs_and_finds_its_kernels(tmp_path):
    src = tmp_path / "src"  # build from a copy: the working tree stays clean
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(
        ".venv", ".git", "build", "dist", "out", "*.egg-info", "__pycache__", ".*cache"))
    subprocess.run([sys.executable, "-m", "build", "--wheel", "--no-isolation",
                    "--outdir", str(tmp_path / "dist"), str(src)],
                   check=True, capture_output=True)
    wheel = next((tmp_path / "dist").glob("clsonar-*.whl"))
    import zipfile
    archive = zipfile.ZipFile(wheel)
    names = archive.namelist()
    assert "clsonar/kernels/echoes.cl" in names and "clsonar/kernels/common.h" in names
    assert {"clsonar/gui/__init__.py", "clsonar/tools/sweep/runners.py",
            "clsonar/tools/stability/map_judge.py"} <= set(names)
    entry_points = next(n for n in names if n.endswith(".dist-info/entry_points.txt"))
    scripts = archive.read(entry_points).decode()
    assert "clsonar = clsonar.cli:main" in scripts and "clsonar-gui = clsonar.gui:main" in scripts

    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    # Dependencies come from this environment's site-packages (appended after the fresh
    # venv's own, so the wheel's clsonar wins); the wheel itself is installed without deps.
    purelib = Path(sysconfig.get_paths(vars={"base": str(venv), "platbase": str(venv)})["purelib"])
    (purelib / "deps.pth").write_text("\n".join(site.getsitepackages()) + "\n")
    py = venv / "bin" / "python"
    subprocess.run([str(py), "-m", "pip", "install", "-q", "--no-deps", "--no-index", str(wheel)],
                   check=True, capture_output=True)

    run = tmp_path / "elsewhere"  # not the source tree, so `import clsonar` means the wheel
    run.mkdir()
    where = subprocess.run([str(py), "-c", "import clsonar; print(clsonar.__file__)"], cwd=run,
                           check=True, capture_output=True, text=True).stdout
    assert str(venv) in where
    out = subprocess.run([str(venv / "bin" / "clsonar"), "echoes", str(ROOT / "scenes" /
                          "plane-2m.json")], cwd=run, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0] == "tx,rx,tof_s,amplitude,kind,order"
    assert len(lines) > 1
