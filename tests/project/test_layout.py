"""The package's layout as docs/design.md draws it: which package may import which, and no loose modules."""

import ast
from pathlib import Path

import emmi_gym

ROOT = Path(emmi_gym.__file__).parent

#: The environment library, bottom up: what each of its packages imports of the others (docs/design.md,
#: "Packages"). The library never imports the tools.
LIBRARY = {
    "inputs": set(),
    "concurrency": {"inputs"},
    "geometry": set(),
    "formats": {"inputs", "geometry"},
    "certainty": {"concurrency"},
    "navigation": {"geometry", "certainty"},
    "world": {"geometry", "inputs", "formats", "navigation"},
    "slam": {"geometry", "inputs", "concurrency", "certainty"},
    "scoring": {"geometry", "certainty", "slam"},
    "env": {"geometry", "inputs", "certainty", "world", "slam", "scoring", "navigation"},
}
#: The tools over the library (``emmi_gym/tools/``), bottom up: what each imports of the library and of the
#: tools below it; ``cli`` is ``tools/cli.py`` (and ``tools/__init__.py``). Training and the experiments both stand
#: on ``evaluation`` and neither imports the other.
TOOLS = {
    "policies": {"world"},
    "evaluation": {"concurrency", "certainty", "formats", "world", "policies"},
    "experiments": {"geometry", "inputs", "concurrency", "certainty", "formats", "world", "slam", "scoring",
                    "policies", "evaluation"},
    "training": {"inputs", "concurrency", "formats", "scoring", "env", "policies", "evaluation"},
    "pretrained": {"inputs", "training"},
    "commands": {"inputs", "concurrency", "certainty", "formats", "world", "slam", "env", "policies", "evaluation",
                 "experiments", "training", "pretrained"},
    "cli": {"commands"},
}
ALLOWED = LIBRARY | TOOLS
#: The tools' old names (``emmi_gym.training``, ``emmi_gym/pretrained.py``, ...): alias modules at the top of the
#: package, each importing the one tools package it names (:mod:`emmi_gym._moved`).
OLD_NAMES = set(emmi_gym.MOVED_TO_TOOLS)


def layer(module: list[str]) -> str | None:
    """The layer of the dotted name ``module`` (split): a library package, a tools package, ``cli``, or None for
    the package's own face (``emmi_gym``, ``emmi_gym.__version__``)."""
    if len(module) < 2:
        return None
    if module[1] != "tools":
        return module[1] if module[1] in LIBRARY else None
    return module[2] if len(module) > 2 and module[2] in TOOLS else "cli"


def imported_layers(source: str, module: list[str]) -> set[str]:
    """The layers the module ``module`` (its dotted name, split) imports in ``source``: relative or absolute,
    at any depth of the file."""
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                target = module[:len(module) - node.level] + (node.module.split(".") if node.module else [])
            elif node.module and node.module.split(".")[0] == "emmi_gym":
                target = node.module.split(".")
            else:
                continue
            targets = [target] if len(target) > 1 and target[-1] != "tools" else \
                [[*target, alias.name] for alias in node.names]
        elif isinstance(node, ast.Import):
            targets = [a.name.split(".") for a in node.names if a.name.startswith("emmi_gym.")]
        else:
            continue
        found |= {name for name in map(layer, targets) if name}
    return found


def modules_of(path: Path) -> tuple[list[str], str]:
    """A file's dotted module name (split) and its layer."""
    module = ["emmi_gym", *path.relative_to(ROOT).with_suffix("").parts]
    return module, layer(module)


def test_the_tree_shows_the_two_halves():
    """The library's packages at the top of ``emmi_gym``, the tools under ``emmi_gym/tools``, the tools' old names
    (aliases), nothing else."""
    top = {p.name for p in ROOT.iterdir() if (p / "__init__.py").is_file()}
    assert top == set(LIBRARY) | {"tools", "worlds_data"} | {name for name in OLD_NAMES if (ROOT / name).is_dir()}
    assert {p.name for p in (ROOT / "tools").iterdir() if (p / "__init__.py").is_file()} == set(TOOLS) - {"cli"}
    assert sorted(p.stem for p in ROOT.glob("*.py")) == sorted({"__init__", "__main__", "_moved"} | OLD_NAMES - top)
    for name in OLD_NAMES:  # each old name is an alias, no code of its own
        alias = ROOT / name / "__init__.py" if name in top else ROOT / f"{name}.py"
        assert f"alias_moved(__name__, {name})" in alias.read_text(), alias
    assert sorted(p.name for p in (ROOT / "tools").glob("*.py")) == ["__init__.py", "cli.py"]


def test_an_import_of_the_tools_from_the_library_is_found():
    slam = ["emmi_gym", "slam", "rbpf"]
    assert imported_layers("from ..tools.training import train", slam) == {"training"}
    assert imported_layers("from ..tools import pretrained", slam) == {"pretrained"}
    assert imported_layers("import emmi_gym.tools.cli", slam) == {"cli"}
    assert imported_layers("from .. import __version__\nfrom ..geometry.grid import G", slam) == {"geometry"}


def test_the_library_never_imports_the_tools():
    """``gymnasium.make`` needs the library only: none of its modules imports training, the experiments, the
    policies, the shipped agents or the command, even inside a function."""
    wrong = [f"{path.relative_to(ROOT)} imports {sorted(found)}" for path in sorted(ROOT.rglob("*.py"))
             if modules_of(path)[1] in LIBRARY
             and (found := imported_layers(path.read_text(), modules_of(path)[0]) & set(TOOLS))]
    assert not wrong, wrong


def test_outside_the_tools_only_their_old_names_and_the_command_import_them():
    """The package's root imports the library (to register the ids) and, lazily in its ``__getattr__``, the
    old name ``emmi_gym.pretrained`` (PEP 562); each old name imports the one tools package it names;
    ``python -m emmi_gym`` runs the command. No other module outside ``emmi_gym/tools`` imports the tools."""
    found = {}
    for path in sorted(ROOT.rglob("*.py")):
        module, own = modules_of(path)
        if own not in LIBRARY and module[1] not in ("tools", "worlds_data"):
            found[".".join(module).removesuffix(".__init__")] = imported_layers(path.read_text(), module) & set(TOOLS)
    assert found.pop("emmi_gym.__main__") == {"cli"}
    assert {name: layers for name, layers in found.items() if layers} == \
        {f"emmi_gym.{name}": {name} for name in OLD_NAMES}
    root = ast.parse((ROOT / "__init__.py").read_text())
    by_name = [(function.name, ast.unparse(node)) for function in ast.walk(root)
               if isinstance(function, ast.FunctionDef) for node in ast.walk(function)
               if isinstance(node, ast.Call) and "import_module" in ast.unparse(node.func)]
    assert by_name == [("__getattr__", "importlib.import_module(f'{__name__}.pretrained')")]


def test_training_and_the_experiments_never_import_each_other():
    """What both need (episodes, their measures, comparisons) is ``evaluation``, below both: training a model
    does not pull in the A/B experiment, and an experiment does not need the ``train`` extra."""
    assert "experiments" not in TOOLS["training"] and "training" not in TOOLS["experiments"]
    assert {"experiments", "training"} & TOOLS["evaluation"] == set()


def test_each_package_imports_only_the_packages_below_it():
    for path in ROOT.rglob("*.py"):
        module, own = modules_of(path)
        if own is None:
            continue
        wrong = imported_layers(path.read_text(), module) - ALLOWED[own] - {own}
        assert not wrong, f"{path.relative_to(ROOT)} imports {sorted(wrong)}, which {own} may not"


def test_only_the_commands_parse_arguments_or_print():
    """The library takes typed arguments and returns results (or reports through a callback it is given):
    argparse and print belong to ``tools/cli.py`` and ``tools/commands/``, as rl-baselines3-zoo keeps them to
    its scripts."""
    found = []
    for path in ROOT.rglob("*.py"):
        relative = path.relative_to(ROOT)
        if relative.parts[:2] == ("tools", "commands") or relative == Path("tools", "cli.py"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            imported = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module] if isinstance(node, ast.ImportFrom) and node.module else []
            if "argparse" in imported:
                found.append(f"{relative}:{node.lineno} imports argparse")
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "print":
                found.append(f"{relative}:{node.lineno} prints")
    assert not found, found


def module_name(path: Path) -> str:
    """The dotted name of a module of the package (a package's ``__init__.py`` is the package itself)."""
    parts = ["emmi_gym", *path.relative_to(ROOT).with_suffix("").parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph() -> dict[str, set[str]]:
    """Module -> the package's modules it imports, from every ``import`` and ``from ... import`` in its
    file: at module level, inside functions and under ``if TYPE_CHECKING`` alike (each says the module
    needs the other). ``from A import b`` links to the module ``A.b`` when ``b`` is a module, else to
    ``A`` (``A``'s ``__init__`` for a package); relative imports are resolved against the module's own
    package."""
    modules = {module_name(path): path for path in ROOT.rglob("*.py")}
    graph = {}
    for name, path in modules.items():
        package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        linked = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                named = node.module.split(".") if node.module else []
                base = ".".join(package[:len(package) - node.level + 1] + named if node.level else named)
                for alias in node.names:
                    if f"{base}.{alias.name}" in modules:
                        linked.add(f"{base}.{alias.name}")
                    elif base in modules:
                        linked.add(base)
            elif isinstance(node, ast.Import):
                linked |= {alias.name for alias in node.names if alias.name in modules}
        graph[name] = linked - {name}
    return graph


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm): each holds a cycle."""
    index, low, stack, on_stack, cycles = {}, {}, [], set(), []

    def visit(module):
        index[module] = low[module] = len(index)
        stack.append(module)
        on_stack.add(module)
        for other in graph[module]:
            if other not in index:
                visit(other)
                low[module] = min(low[module], low[other])
            elif other in on_stack:
                low[module] = min(low[module], index[other])
        if low[module] == index[module]:
            component = []
            while not component or component[-1] != module:
                component.append(stack.pop())
                on_stack.discard(component[-1])
            if len(component) > 1:
                cycles.append(sorted(component))

    for module in sorted(graph):
        if module not in index:
            visit(module)
    return cycles


def test_import_cycles_are_found():
    assert import_cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert import_cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycle_among_the_modules():
    """A module can be read, tested and changed knowing only the modules below it: none imports, even for
    type hints only, a module that imports it back, directly or through others."""
    graph = import_graph()
    assert "emmi_gym.env.actions" in graph["emmi_gym.env.emmi_env"]  # the graph resolves relative imports
    assert import_cycles(graph) == []


def private_reaches(source: str) -> list[str]:
    """Where ``source`` reads or writes another object's underscore attribute: ``x._name`` for any ``x``
    but ``self``, ``cls`` and ``super()`` (whose privates are the class's own). Dunder attributes
    (``__name__``, ``__class__``) are the language's public protocol and do not count; nor do names a
    module imports (a package's private module, ``from . import _kernels``, is the package's own), nor
    ``getattr`` with a string. One line each: ``line: expression``."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if not (isinstance(node, ast.Attribute) and node.attr.startswith("_")):
            continue
        if node.attr.startswith("__") and node.attr.endswith("__"):
            continue
        owner = node.value
        if isinstance(owner, ast.Name) and owner.id in ("self", "cls"):
            continue
        if isinstance(owner, ast.Call) and isinstance(owner.func, ast.Name) and owner.func.id == "super":
            continue
        found.append((node.lineno, node.col_offset, ast.unparse(node)))
    return [f"{line}: {expression}" for line, _, expression in sorted(found)]


def test_private_reaches_are_found():
    source = "self._a = env._b\ncls._c\nsuper()._d()\nx.__class__\nmodule._e()\nself.env._f = 1\n"
    assert private_reaches(source) == ["1: env._b", "5: module._e", "6: self.env._f"]


def test_no_module_reaches_into_another_objects_private_attributes():
    """A class's underscore attributes are its own to rename: a module that reads or writes them on another
    object (the env's private step from an action type) breaks silently when they change."""
    reaches = {str(path.relative_to(ROOT)): found for path in sorted(ROOT.rglob("*.py"))
               if (found := private_reaches(path.read_text()))}
    assert reaches == {}


def is_private(name: str) -> bool:
    """An underscore name that is not a dunder (``_last_obs``, not ``__init__``)."""
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def privates_of_self(cls: ast.ClassDef, methods=None, stored: bool = False) -> set[str]:
    """The underscore attributes of ``self`` that the methods of ``cls`` (those named in ``methods``, if given)
    read or write (only those they assign, with ``stored``)."""
    return {node.attr for method in cls.body if isinstance(method, ast.FunctionDef)
            and (methods is None or method.name in methods) for node in ast.walk(method)
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "self"
            and is_private(node.attr) and (not stored or isinstance(node.ctx, ast.Store))}


def private_names_defined(cls: ast.ClassDef) -> set[str]:
    """The underscore names the body of ``cls`` defines: its methods, nested classes and class attributes."""
    names = {node.name for node in cls.body if isinstance(node, (ast.FunctionDef, ast.ClassDef))}
    names |= {target.id for node in cls.body if isinstance(node, ast.Assign) for target in node.targets
              if isinstance(target, ast.Name)}
    names |= {node.target.id for node in cls.body
              if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)}
    return {name for name in names if is_private(name)}


def undeclared_privates(source: str) -> dict[str, list[str]]:
    """For each class of ``source``: the ``self._name`` its methods read or write that neither its body, nor its
    ``__init__``, nor a base class of the same module declares: a private it inherits from a class of another
    library (SB3's ``self._last_obs``), whose owner may rename it or change what it means."""
    classes = {node.name: node for node in ast.walk(ast.parse(source)) if isinstance(node, ast.ClassDef)}

    def declared(cls: ast.ClassDef) -> set[str]:
        bases = [classes[b.id] for b in cls.bases if isinstance(b, ast.Name) and b.id in classes]
        own = private_names_defined(cls) | privates_of_self(cls, ("__init__",), stored=True)
        return own.union(*(declared(base) for base in bases))

    return {name: sorted(used) for name, cls in classes.items() if (used := privates_of_self(cls) - declared(cls))}


def test_undeclared_privates_are_found():
    source = ("class A(Base):\n    def __init__(self):\n        self._a = 1\n    def _own(self):\n        pass\n"
              "    def step(self):\n        self._own()\n        self._a = self._last_obs\n        self._b = 2\n"
              "class B(A):\n    def go(self):\n        return self._a, self._update_info_buffer(), self.__class__\n")
    assert undeclared_privates(source) == {"A": ["_b", "_last_obs"], "B": ["_update_info_buffer"]}


def test_no_class_uses_a_private_it_inherits_from_another_library():
    """A class of the package writes and reads only the underscore attributes it declares (or a base class beside
    it does): an override such as rollout workers' ``collect_rollouts`` goes through the public names of the
    library it extends, never the private state of its base class (``tests/project/test_imports.py`` checks
    that no private a class declares is also one of a library's base class)."""
    found = {str(path.relative_to(ROOT)): used for path in sorted(ROOT.rglob("*.py"))
             if (used := undeclared_privates(path.read_text()))}
    assert found == {}


def attributes_set_outside_init(source: str) -> dict[str, list[str]]:
    """For each class of ``source``: the ``self.`` attributes its other methods assign that neither its
    ``__init__`` nor the ``__init__`` of a base class of the same module assigns."""
    classes = {node.name: node for node in ast.walk(ast.parse(source)) if isinstance(node, ast.ClassDef)}

    def assigned(cls: ast.ClassDef) -> dict[str, set[str]]:
        by_method = {}
        for method in (f for f in cls.body if isinstance(f, ast.FunctionDef)):
            targets = [t for n in ast.walk(method) for t in (n.targets if isinstance(n, ast.Assign) else
                       [n.target] if isinstance(n, (ast.AugAssign, ast.AnnAssign)) else [])]
            by_method[method.name] = {e.attr for t in targets for e in ast.walk(t) if isinstance(e, ast.Attribute)
                                      and isinstance(e.value, ast.Name) and e.value.id == "self"}
        return by_method

    def declared(cls: ast.ClassDef) -> set[str]:
        bases = [classes[b.id] for b in cls.bases if isinstance(b, ast.Name) and b.id in classes]
        return assigned(cls).get("__init__", set()).union(*(declared(base) for base in bases))

    found = {}
    for name, cls in classes.items():
        late = {a for method, names in assigned(cls).items() if method != "__init__" for a in names} - declared(cls)
        if late:
            found[name] = sorted(late)
    return found


def test_attributes_set_outside_init_are_found():
    source = ("class A:\n    def __init__(self):\n        self.a = 1\n"
              "    def reset(self):\n        self.a = self.b = 2\n"
              "class B(A):\n    def go(self):\n        self.a += 1\n        self.c: int = 3\n")
    assert attributes_set_outside_init(source) == {"A": ["b"], "B": ["c"]}


def test_the_environment_classes_declare_every_attribute_in_init():
    """What an environment, its episode, action and observation types hold can be read off their
    ``__init__``: no attribute first appears in a method called later."""
    late = {str(path.relative_to(ROOT)): found for path in sorted((ROOT / "env").glob("*.py"))
            if (found := attributes_set_outside_init(path.read_text()))}
    assert late == {}
