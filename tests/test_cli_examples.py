"""Every recipe, scene and groom file that the CLI's help examples name is in the repository."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_example_inputs_exist():
    named = set()
    for path in sorted((ROOT / "cli").glob("*.py")):
        named |= {m.group(0) for m in re.finditer(r"tables/[\w./-]+\.(?:toml|tfx|hair|usda)\b", path.read_text())}
    assert named, "no examples found"
    missing = sorted(p for p in named if not (ROOT / p).is_file())
    assert not missing, f"help examples name files a clone lacks: {missing}"
