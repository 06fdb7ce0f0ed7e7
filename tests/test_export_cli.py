"""``geosyn export`` writes a library that the README's C example compiles against and
runs as printed (its torque checked against Pinocchio's gravity torque), that CMake finds
with find_package, and refuses bad requests with exit code 2 and one line."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from geosyn.experiments.cli import main
from geosyn.robots import load_robot

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="needs a C compiler")


def found(pattern: str, text: str, flags: int = 0) -> re.Match[str]:
    match = re.search(pattern, text, flags)
    assert match is not None, pattern
    return match


def readme_section() -> str:
    text = (ROOT / "README.md").read_text()
    start = text.index("## Use the controller from C/C++")
    return text[start : text.index("\n## ", start + 10)]


@pytest.fixture(scope="module")
def panda_ct(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The README's export command, run through the CLI."""
    command = found(r"```bash\n(geosyn export [^\n#]*)", readme_section()).group(1).split()
    out = tmp_path_factory.mktemp("cli") / "panda_ct"
    assert command[1:5] == ["export", "panda", "--controller", "computed_torque"]
    assert main([*command[1:-1], str(out)]) == 0
    return out


def test_readme_c_example_compiles_and_prints_what_the_readme_shows(
    panda_ct: Path, tmp_path: Path
) -> None:
    section = readme_section()
    source = found(r"```c\n(.*?)```", section, re.S).group(1)
    printed = found(r"prints\n\n```\n(.*?)```", section, re.S).group(1)
    assert 15 <= source.count("\n") <= 25
    (tmp_path / "example.c").write_text(source)
    exe = tmp_path / "example"
    subprocess.run(
        ["nice", "-n", "10", "cc", "-O2", f"-I{panda_ct}", "example.c",
         str(panda_ct / "libgeosyn_controller.a"), "-lm", "-o", str(exe)],
        cwd=tmp_path, check=True,
    )  # fmt: skip
    out = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout
    assert out == printed
    # holding a pose at rest, computed torque is the gravity torque: Pinocchio's
    robot = load_robot("panda")
    q = 0.1 * np.arange(robot.nq)
    g = pin.computeGeneralizedGravity(robot.model, robot.model.createData(), q)
    shown = [float(x) for x in found(r"tau (\S+) (\S+) N m", out).groups()]
    np.testing.assert_allclose(shown, g[:2], atol=5e-4)


def test_cmake_finds_the_package(panda_ct: Path, tmp_path: Path) -> None:
    if shutil.which("cmake") is None:
        pytest.skip("needs cmake")
    (tmp_path / "main.c").write_text(
        '#include "geosyn_controller.h"\n'
        "int main(void) { geosyn_controller* c = geosyn_controller_create();\n"
        "  int n = geosyn_controller_nq(c); geosyn_controller_destroy(c); return n == 7 ? 0 : 1; }\n"
    )
    (tmp_path / "CMakeLists.txt").write_text(
        "cmake_minimum_required(VERSION 3.13)\nproject(app C)\n"
        f'find_package(geosyn_controller REQUIRED PATHS "{panda_ct}" NO_DEFAULT_PATH)\n'
        "add_executable(app main.c)\n"
        "target_link_libraries(app PRIVATE geosyn_controller::static)\n"
    )
    build = tmp_path / "build"
    subprocess.run(
        ["cmake", "-S", str(tmp_path), "-B", str(build)], check=True, capture_output=True
    )
    subprocess.run(
        ["nice", "-n", "10", "cmake", "--build", str(build)], check=True, capture_output=True
    )
    assert subprocess.run([str(build / "app")]).returncode == 0


def test_export_refuses_bad_requests(panda_ct: Path, tmp_path: Path, capsys) -> None:
    assert main(["export", "panda", "--controller", "qp", "--out", str(tmp_path / "a")]) == 2
    assert "QPController cannot be exported" in capsys.readouterr().err
    assert main(["export", "panda", "--controller", "pd", "--out", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err
    assert "'pd'" in err and "riemannian_pd" in err  # the valid types are named
    yaml_file = tmp_path / "arm.yaml"
    assert main(["init", "arm", "--robot", "ur5", "--out", str(yaml_file)]) == 0
    capsys.readouterr()
    args = ["export", str(yaml_file), "--controller", "riemannian_pd", "--out", str(tmp_path / "d")]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "no controller 'riemannian_pd'" in err and "computed_torque, qp" in err
    args = ["export", "panda", "--controller", "computed_torque", "--out", str(panda_ct)]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not empty" in err and "--force" in err
    assert main(["export", "panda", "--out", str(tmp_path / "b")]) == 2  # --controller needed
