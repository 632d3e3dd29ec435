"""What a wheel (``pip install .``, not the editable install) carries: every data file the
package reads at run time, i.e. every file under the packages that is not Python source,
is named by pyproject's ``[tool.setuptools.package-data]`` (a shipped graph left out once
made every ``cekm run`` of an installed wheel end in a traceback)."""

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS_ONLY = {"README.md"}  # read by people, not by the package
BUILT = {".py", ".pyc", ".nbi", ".nbc"}  # source, and what Python and numba cache beside it


def data_files(*dirs: str) -> list[Path]:
    return sorted(p.relative_to(ROOT) for d in dirs for p in (ROOT / d).rglob("*")
                  if p.is_file() and p.suffix not in BUILT and p.name not in DOCS_ONLY
                  and "__pycache__" not in p.parts)


def test_every_data_file_of_the_packages_is_package_data():
    setuptools = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    globs = setuptools["package-data"]
    files = data_files("cekm_swarm", "world")
    assert files
    missing = []
    for path in files:
        owners = [pkg for pkg in globs if path.is_relative_to(Path(*pkg.split(".")))]
        ok = any(path.relative_to(Path(*pkg.split("."))).match(g) for pkg in owners for g in globs[pkg])
        if not ok:
            missing.append(str(path))
    assert not missing, f"not in [tool.setuptools.package-data]: {missing}"


def test_package_data_globs_name_packages_that_exist():
    globs = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    for pkg in globs:
        assert (ROOT / Path(*pkg.split(".")) / "__init__.py").is_file(), pkg
