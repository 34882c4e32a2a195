"""The package's layout as docs/design.md draws it: which package may import which, and no loose modules."""

import ast
from pathlib import Path

import emmi_gym

ROOT = Path(emmi_gym.__file__).parent

#: What each package imports of the others (docs/design.md, "Packages"): imports point down this table.
ALLOWED = {
    "inputs": set(),
    "concurrency": set(),
    "geometry": set(),
    "formats": {"inputs"},
    "certainty": {"concurrency"},
    "navigation": {"geometry", "certainty"},
    "world": {"geometry", "inputs", "formats", "navigation"},
    "slam": {"geometry", "inputs", "concurrency", "certainty"},
    "scoring": {"geometry", "certainty", "slam"},
    "env": {"geometry", "inputs", "certainty", "world", "slam", "scoring", "navigation"},
    "policies": {"world"},
    "experiments": {"geometry", "inputs", "concurrency", "certainty", "formats", "world", "slam", "scoring",
                    "policies"},
    "training": {"inputs", "concurrency", "env", "policies", "experiments"},
    "pretrained": {"training"},
}


def imported_packages(path: Path) -> set[str]:
    """The emmi_gym packages a module imports (relative or absolute, at any depth of the file)."""
    module = ["emmi_gym", *path.relative_to(ROOT).with_suffix("").parts]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                target = module[:len(module) - node.level] + (node.module.split(".") if node.module else [])
            elif node.module and node.module.split(".")[0] == "emmi_gym":
                target = node.module.split(".")
            else:
                continue
            found |= {target[1]} if len(target) > 1 else {alias.name for alias in node.names}
        elif isinstance(node, ast.Import):
            found |= {a.name.split(".")[1] for a in node.names if a.name.startswith("emmi_gym.")}
    return found


def test_each_package_imports_only_the_packages_below_it():
    packages = {p.name for p in ROOT.iterdir() if (p / "__init__.py").is_file()} - {"worlds_data"}
    assert packages == set(ALLOWED)
    for package in packages:
        for path in (ROOT / package).rglob("*.py"):
            wrong = imported_packages(path) - ALLOWED[package] - {package, "__version__"}
            assert not wrong, f"{path.relative_to(ROOT)} imports {sorted(wrong)}, which {package} may not"


def test_no_loose_modules_beside_the_packages():
    assert sorted(p.name for p in ROOT.glob("*.py")) == ["__init__.py", "cli.py"]
