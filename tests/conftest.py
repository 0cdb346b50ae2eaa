import os

import pytest

from corpus import CORPUS


def pytest_collection_modifyitems(config, items):
    # The corpus sits beside the checkout (../shared); CI always has it.
    if not (CORPUS / "MANIFEST.tsv").exists():
        if os.environ.get("CI"):
            raise pytest.UsageError(f"Gerber corpus not found at {CORPUS}")
