"""The hardening audit (``hardening_audit.py`` beside this file, ``python tests/hardening/hardening_audit.py``):
its hostile inputs run here as tests, each refused with an error of the package's own (a message naming the file,
field or option) or handled, in little memory; and the audit's own machinery (the probes' runner, the verdicts,
the generators of large inputs in few bytes) does what its tables rely on."""

import gzip
import sys
import zipfile
import zlib

import pytest
from hardening_audit import (
    _deflate_repeated,
    _gzip_repeated,
    _png,
    _zip_with_huge_member,
    cases,
    compile_filter_kernels,
    run_case,
    run_probe,
)
from PIL import Image
from training_probes import LIMIT_SECONDS, Probe, digest, verdict

#: The cases that play episodes (a reset and a step, of every id for the pickling ones): seconds each.
SLOW_CASES = {"laser max_range=0.5: map_accuracy", *(f"pickle and deepcopy {name} after reset and a step"
                                                    for name in ("LoopCorridor-v1", "LoopOrder-v1", "ExplorePlans-v1"))}
#: The cases whose input is fine (the audit checked that it is not refused): what each must return.
HANDLED = {"1.0e1 in a world file": "ok: box", "log driving straight along an axis": "ok: 5",
           "all-zero scans": "ok: ['1 scans have no echo (every range 0): they add nothing to the map']",
           "laser max_range=0.5: map_accuracy": "ok: stepped; map_accuracy 0.000"}


@pytest.fixture(scope="module")
def audit_cases(tmp_path_factory):
    compile_filter_kernels()  # the cases' 60 s are for their inputs, not for numba compiling on a cold cache
    return dict(cases(tmp_path_factory.mktemp("cases")))


def case_labels() -> list:
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as folder:
        labels = [label for label, _ in cases(Path(folder))]
    return [pytest.param(label, marks=pytest.mark.slow) if label in SLOW_CASES else label for label in labels]


@pytest.mark.parametrize("label", case_labels())
def test_each_hostile_input_is_refused_by_an_error_of_the_package_or_handled(label, audit_cases):
    case = run_case(audit_cases[label], limit=60.0)
    if label in HANDLED or label.startswith("pickle and deepcopy"):
        assert case.outcome == HANDLED.get(label, "ok: both copies made")
    else:
        assert case.error is not None, f"{label}: accepted ({case.outcome})"
        kind = type(case.error)
        assert kind.__module__.startswith("emmi_gym."), f"{label}: a raw {kind.__module__}.{case.outcome}"
        assert str(case.error).strip(), f"{label}: {kind.__name__} without a message"
    assert case.peak_mb < 1024


def test_a_case_over_its_time_limit_is_stopped_and_said_so():
    import time

    case = run_case(lambda: time.sleep(5), limit=1)
    assert case.outcome == "TimeoutError: still running after 1 s" and case.seconds < 3


def test_the_probes_runner_reports_the_exit_the_last_line_and_a_traceback():
    done = run_probe([sys.executable, "-c", "print('one'); print('two'); raise SystemExit(3)"])
    assert (done["rc"], done["last"], done["killed"], done["traceback"]) == (3, "two", None, False)
    failed = run_probe([sys.executable, "-c", "raise KeyError('x')"])
    assert failed["rc"] == 1 and failed["traceback"] and failed["last"] == "KeyError: 'x'"
    assert 0 < done["peak_mb"] < 200 and done["seconds"] < LIMIT_SECONDS


def test_the_probes_runner_kills_a_probe_at_its_time_limit_and_keeps_its_last_output():
    done = run_probe([sys.executable, "-c", "import time; print('started', flush=True); time.sleep(30)"], limit=1.0)
    assert done["killed"] == "1 s" and done["rc"] == -9 and done["last"] == "started" and done["seconds"] < 10


def test_a_verdict_tells_a_clear_error_from_a_silent_wrong_result_a_traceback_and_data_loss(tmp_path):
    quiet = {"killed": None, "seconds": 1.0, "peak_mb": 100.0, "traceback": False}
    refuse = Probe("refuse", [], error=r"field 'x'")
    assert verdict(refuse, dict(quiet, rc=2, last="error: field 'x': expected 1"), []) == \
        ("clear error", "names what is wrong")
    assert verdict(refuse, dict(quiet, rc=2, last="error: something"), [])[0] == "SILENT WRONG"
    assert verdict(refuse, dict(quiet, rc=0, last="done"), [])[0] == "SILENT WRONG"
    assert verdict(refuse, dict(quiet, rc=1, last="x", traceback=True), [])[0] == "TRACEBACK"
    assert verdict(refuse, dict(quiet, rc=2, last="field 'x'"), ["model.zip"]) == ("DATA LOSS", "changed model.zip")
    assert verdict(refuse, dict(quiet, rc=2, last="field 'x'", peak_mb=2000.0), [])[0] == "LIMIT"
    succeed = Probe("succeed", [], success=lambda last, _: None if last == "wrote x" else f"said {last!r}")
    assert verdict(succeed, dict(quiet, rc=0, last="wrote x"), []) == ("ok", "did what it should")
    assert verdict(succeed, dict(quiet, rc=0, last="wrote y"), []) == ("SILENT WRONG", "said 'wrote y'")
    kept = tmp_path / "kept"
    kept.write_text("a")
    before = digest([kept, tmp_path / "absent"])
    kept.write_text("b")
    assert [p for p, d in digest([kept, tmp_path / "absent"]).items() if before[p] != d] == [str(kept)]


def test_the_large_inputs_are_made_of_few_bytes_that_unpack_to_what_they_say(tmp_path):
    chunk = b"FLASER 1 2\n" * 1000
    assert zlib.decompress(_deflate_repeated(chunk, 50, wbits=15)) == chunk * 50
    assert zlib.decompress(_deflate_repeated(chunk, 50), wbits=-15) == chunk * 50
    _gzip_repeated(tmp_path / "log.gz", chunk, 300)
    assert gzip.decompress((tmp_path / "log.gz").read_bytes()) == chunk * 300
    assert (tmp_path / "log.gz").stat().st_size < len(chunk) * 300 / 100
    _zip_with_huge_member(tmp_path / "model.zip", "data", 8 << 20, chunk_size=1 << 20)
    with zipfile.ZipFile(tmp_path / "model.zip") as archive:
        assert archive.getinfo("data").file_size == 8 << 20 and archive.read("data") == bytes(8 << 20)
    with Image.open(_png(tmp_path / "plan.png", 30, 20)) as plan:
        assert plan.size == (30, 20) and plan.mode == "L" and plan.getextrema() == (255, 255)


@pytest.mark.slow  # a process of its own that imports the package
def test_a_probe_of_a_gigabyte_of_zeros_in_a_small_gzip_is_a_clear_error_of_the_replay(tmp_path):
    _gzip_repeated(tmp_path / "zeros.log.gz", bytes(1 << 20), 1024)  # 1 GiB of NUL bytes
    done = run_probe([sys.executable, "-m", "emmi_gym.tools.cli", "replay", str(tmp_path / "zeros.log.gz"),
                      "--max-range", "8", "--out", str(tmp_path / "out")])
    assert done["rc"] == 2 and not done["traceback"] and done["killed"] is None
    assert done["last"].endswith("zeros.log.gz: expected a CARMEN log, which is text, not binary data "
                                 "(NUL bytes from byte 0)")
    assert done["peak_mb"] < 1024
