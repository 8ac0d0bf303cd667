"""calib.yaml_guard: hostile and botched YAML is refused fast, on one line, without echoing it."""

import time

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from calib.yaml_guard import (
    MAX_DEPTH,
    MAX_FILE_BYTES,
    MAX_SCALAR_CHARS,
    MAX_SHOWN_CHARS,
    YamlRefused,
    parse_yaml,
    read_yaml,
    shown,
)


def alias_bomb(levels: int = 9) -> str:
    """``levels`` lines of nested aliases: 9**levels strings when expanded."""
    lines = ['a0: &a0 ["x","x","x","x","x","x","x","x","x"]']
    for i in range(1, levels):
        lines.append(f"a{i}: &a{i} [" + ",".join([f"*a{i - 1}"] * 9) + "]")
    return "\n".join(lines) + "\n"


def test_plain_yaml_reads_a_bomb_and_files_too_large_or_not_regular_are_refused(tmp_path):
    text = "name: sim\npan: {id: 1, min_deg: -115.0}\nlist: [1, 2.5, x]\nwhen: 2024-01-02\n"
    assert parse_yaml(text) == yaml.safe_load(text)
    # the same key in two different mappings, and nesting up to the limit, are fine
    assert parse_yaml("pan: {id: 1}\ntilt: {id: 2}\n") == {"pan": {"id": 1}, "tilt": {"id": 2}}
    assert parse_yaml("[" * (MAX_DEPTH - 1) + "]" * (MAX_DEPTH - 1)) is not None
    started = time.perf_counter()
    with pytest.raises(YamlRefused, match=r"^line 1: anchors and aliases") as err:
        parse_yaml(alias_bomb())
    assert time.perf_counter() - started < 1.0
    assert "\n" not in str(err.value)
    assert shown(10**5000) == "<an integer of about 5001 digits>"
    assert shown(12345) == "12345"
    assert "..." in shown("x" * 1000) and len(shown("x" * 1000)) <= MAX_SHOWN_CHARS
    big = tmp_path / "big.yaml"
    big.write_bytes(b"# " + b"x" * MAX_FILE_BYTES + b"\n")
    started = time.perf_counter()
    with pytest.raises(YamlRefused, match="larger than 64 KiB"):
        read_yaml(big)
    assert time.perf_counter() - started < 1.0
    with pytest.raises(YamlRefused, match="not a regular file"):
        read_yaml(tmp_path)
    with pytest.raises(FileNotFoundError):
        read_yaml(tmp_path / "missing.yaml")
    binary = tmp_path / "binary.yaml"
    binary.write_bytes(b"name: \xff\xfe\n")
    with pytest.raises(YamlRefused, match="not UTF-8 text"):
        read_yaml(binary)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("a: 1\nb: *a\n", "line 2: anchors and aliases"),
        ("pan:\n  <<: {min_deg: -170}\n  min_deg: -10\n", "line 2: merge keys"),
        (
            "pan:\n  max_deg: 70.0\n  id: 1\n  max_deg: 170.0\n",
            r"line 4: key 'max_deg' appears twice \(also on line 2\)",
        ),
        ("{a: 1, a: 2}", "line 1: key 'a' appears twice"),
        ("[" * 20_000 + "]" * 20_000, f"nested more than {MAX_DEPTH} levels"),  # no RecursionError
        # 60,000 digits: PyYAML's own int() would raise ValueError (Python's 4,300-digit limit)
        ("baud: " + "9" * 60_000 + "\n", "a value of 60000 characters"),
        ("name: " + "x" * (MAX_SCALAR_CHARS + 1) + "\n", f"at most {MAX_SCALAR_CHARS}"),
        ("when: 2001-02-30\n", "a value cannot be read"),  # PyYAML raises ValueError
        ("name: sim\npan: [1, 2\ntilt: {id: 2}\n", r"not valid YAML \(line 3, column 5: expected "),
    ],
)
def test_harmful_or_botched_yaml_is_refused_on_one_line(text, match):
    with pytest.raises(YamlRefused, match=match) as err:
        parse_yaml(text)
    assert "\n" not in str(err.value)


@settings(max_examples=200, deadline=None)
@given(
    value=st.recursive(
        st.none()
        | st.booleans()
        | st.integers(min_value=-(10**4000), max_value=10**4000)
        | st.floats()
        | st.text(max_size=5000),
        lambda inner: st.lists(inner, max_size=50) | st.dictionaries(st.text(), inner),
        max_leaves=200,
    )
)
def test_shown_is_bounded_and_never_raises(value):
    text = shown(value)
    assert len(text) <= MAX_SHOWN_CHARS
