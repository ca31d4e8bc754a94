"""tests/_warmup.py's file sets: a test file that needs the check kernels runs after their warm-up.

A file that calls ``check_batch`` but is missing from the check warm-up's set sorts where its name
puts it and compiles the check kernels (minutes, the largest of the package) in the main process
while the warm-up compiles the same ones on the other core (test_adversary_decide and test_cli did,
found by CI's durations in session 45; test_readme's check_batch example, in session 47).
"""

import re
from pathlib import Path

from _warmup import WARMUPS, _check

TESTS = Path(__file__).resolve().parent
README = TESTS.parent / "README.md"


def test_every_file_calling_check_batch_waits_for_the_check_warm_up():
    names = next(n for n, fn in WARMUPS if fn is _check)
    calling = {p.name for p in TESTS.glob("test_*.py") if re.search(r"\.check_batch\(", p.read_text())}
    if re.search(r"\.check_batch\(", README.read_text()):
        calling.add("test_readme.py")  # runs the README's examples
    assert "test_check.py" in calling  # the scan finds what it is for
    assert not calling - names, sorted(calling - names)


def test_the_warm_up_sets_name_existing_files_once():
    seen = [name for names, _ in WARMUPS for name in names]
    assert len(seen) == len(set(seen))
    assert all((TESTS / name).is_file() for name in seen), [n for n in seen if not (TESTS / n).is_file()]
