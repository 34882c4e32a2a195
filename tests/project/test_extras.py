"""Without an optional extra, every command and the pretrained API say which extra is missing and the line
that installs it (exit 2 for a command), never a raw ModuleNotFoundError."""

import subprocess
import sys
import textwrap

import pytest

from emmi_gym.inputs.extras import CPU_TORCH, MissingExtraError, extra_of, install_command, missing_extra

#: Run in a fresh interpreter in which the named top-level modules cannot be imported, as after
#: ``pip install emmi-gym`` without the extra.
_WITHOUT = textwrap.dedent("""
    import sys
    BLOCKED = set(sys.argv[1].split(","))
    class NotInstalled:
        def find_spec(self, name, path=None, target=None):
            if name.partition(".")[0] in BLOCKED:
                raise ModuleNotFoundError(f"No module named {name!r}", name=name)
    sys.meta_path.insert(0, NotInstalled())
    del sys.argv[1]
""")
TRAIN_MODULES = "stable_baselines3,sb3_contrib,torch,tensorboard"


def run_without(modules: str, code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", _WITHOUT + textwrap.dedent(code), modules],
                          capture_output=True, text=True, timeout=300)


def cli_without(modules: str, *argv: str) -> subprocess.CompletedProcess:
    return run_without(modules, f"from emmi_gym.tools.cli import main\nsys.exit(main({list(argv)!r}))")


def test_each_extra_is_named_by_its_modules():
    assert extra_of("stable_baselines3.common.vec_env") == "train"
    assert extra_of("torch") == "train"
    assert extra_of("ray") == "ray"
    assert extra_of("pygame") == "viz"
    assert extra_of("numpy") is None and extra_of(None) is None
    assert install_command("train").startswith(CPU_TORCH)  # the CPU build, not several GB of CUDA
    assert install_command("ray") == 'pip install "emmi-gym[ray]"'
    error = missing_extra(ModuleNotFoundError("No module named 'sb3_contrib'", name="sb3_contrib"), "evaluating")
    assert isinstance(error, MissingExtraError) and isinstance(error, ImportError)
    assert "'train' extra" in str(error) and CPU_TORCH in str(error) and "\n" not in str(error)
    assert missing_extra(ModuleNotFoundError("No module named 'scipy'", name="scipy"), "x") is None


@pytest.mark.slow
@pytest.mark.parametrize("argv", [
    ("evaluate", "--pretrained", "loop_order_emmi", "--episodes", "3"),
    ("train", "agents/ppo_emmi.yaml", "--timesteps", "8", "--out", "{tmp}/run"),
    ("score-checkpoints", "{tmp}/nothing"),
])
def test_commands_without_the_train_extra_print_the_install_line(argv, tmp_path):
    result = cli_without(TRAIN_MODULES, *(arg.format(tmp=tmp_path) for arg in argv))
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    lines = [line for line in result.stderr.strip().splitlines()
             if not line.startswith("first run: numba compiles")]  # said once, before the kernels are cached
    assert len(lines) == 1 and f"'{argv[0]}' needs the 'train' extra" in lines[0] and CPU_TORCH in lines[0]
    assert not (tmp_path / "run").exists()  # refused before anything was written


@pytest.mark.slow
def test_ray_option_without_ray_names_the_ray_extra(tmp_path):
    result = cli_without("ray", "train", "agents/ppo_emmi.yaml", "--timesteps", "8", "--ray", "local",
                         "--out", str(tmp_path / "run"))
    assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr
    assert "Ray needs the 'ray' extra" in result.stderr and 'pip install "emmi-gym[ray]"' in result.stderr


def test_pretrained_snippet_without_the_train_extra():
    result = run_without(TRAIN_MODULES, """
        import emmi_gym
        env = emmi_gym.pretrained.make_env("loop_order_emmi")  # the env needs no extra
        env.close()
        try:
            emmi_gym.pretrained.load("loop_order_emmi")
        except ImportError as error:
            print(type(error).__name__, error)
    """)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("MissingExtraError emmi_gym.pretrained.load('loop_order_emmi') needs the "
                                    "'train' extra")
    assert CPU_TORCH in result.stdout
