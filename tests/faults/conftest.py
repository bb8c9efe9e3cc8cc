"""The fault suite: fault injection, as a user meets faults. Every case runs ``python -m fenestra
...`` (the ``fenestra`` command) in a subprocess (docs/DESIGN.md: "What Fenestra guarantees"),
most of them as rows of a table (case, how the bad input is built, what the one error line must
say), one file per subject:

- test_ownership.py: nothing of the user's is replaced or deleted; atomic output, another filesystem;
- test_cli_faults.py: bad input through the CLI (intrinsics, OS errors, odd files, a user's inputs,
  the Python API's arguments), Ctrl-C;
- test_dataset_faults.py: a user's dataset (paths inside it, bounded labels, unique stems);
- test_gate_faults.py, test_digest_faults.py: results that cannot be forged or silently shortened;
- test_render_cache_faults.py, test_memory_faults.py, test_plugin_faults.py;
- test_count_faults.py: every count bounded at load (fenestra.conventions.LIMITS), memory on the
  largest admitted photo;
- test_user_error_faults.py: more user errors as one bounded line (summary.json, K.json, names);
- test_output_kinds.py: no command crosses kinds of output or replaces a file it did not write or
  read; bench, report, compare, bench again; a killed run runs again; one reconstruct per folder;
- test_batch_faults.py: a batch's photo folders, whatever the photos are named;
- test_ray_shards.py: a run on a live local Ray cluster lists its shards, and recognises an unlisted one.

fault_helpers.py holds what they share. Disk full is a real failing write: the child runs under
RLIMIT_FSIZE (a file-size limit the kernel enforces with EFBIG, SIGXFSZ ignored), so cv2.imwrite
and friends fail mid-run exactly as on a full disk. A read-only output is a read-only tmpfs when
running as root (root ignores file modes), else a folder with mode 0o555.

pytest puts this folder on sys.path (rootdir-less test files: "prepend" import mode), not tests/;
the fixture modules in tests/ (synthetic_results, toy_data, ...) are imported from here too, so
tests/ is put on sys.path below. ``pytest`` (testpaths = tests) collects this folder;
``pytest tests/faults`` runs the suite alone.
"""
import sys
from pathlib import Path

TESTS = str(Path(__file__).resolve().parent.parent)
if TESTS not in sys.path:
    sys.path.insert(0, TESTS)
