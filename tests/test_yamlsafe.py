import pytest

from atemr.errors import ConfigError
from atemr.yamlsafe import MAX_DEPTH, key_mark_of, load_yaml, mark_of


def load(text: str):
    return load_yaml("doc.yaml", text=text)


def test_values_remember_their_line_and_column():
    doc = load("a: 1\nb:\n  c: [1, 2]\n  d:\n    - x\n    - y\n")
    assert mark_of(doc, "a") == (1, 4)
    assert key_mark_of(doc["b"], "d") == (4, 3)
    assert mark_of(doc["b"]["d"], 1) == (6, 7)
    assert doc == {"a": 1, "b": {"c": [1, 2], "d": ["x", "y"]}}


def test_duplicate_keys_are_refused_with_both_places():
    with pytest.raises(ConfigError) as err:
        load("a: 1\nb: 2\na: 3\n")
    assert err.value.line == 3 and err.value.column == 1
    assert "duplicate key 'a' (first defined at line 1)" in str(err.value)
    assert str(err.value).startswith("doc.yaml:3:1")


def test_python_tags_are_refused():
    with pytest.raises(ConfigError, match="unsafe or unknown tag") as err:
        load("x: !!python/object/apply:os.system ['echo hi']\n")
    assert err.value.line == 1


def test_syntax_errors_name_line_and_column():
    with pytest.raises(ConfigError) as err:
        load("a: [1, 2\nb: 3\n")
    assert err.value.file == "doc.yaml" and err.value.line is not None


def test_huge_documents_are_refused_before_parsing():
    with pytest.raises(ConfigError, match="more than the limit"):
        load_yaml("big.yaml", text="a: " + "x" * 2_000_000)


def test_deep_nesting_is_refused():
    with pytest.raises(ConfigError, match="nested more than"):
        load("[" * (MAX_DEPTH + 5) + "]" * (MAX_DEPTH + 5))


def test_alias_bombs_are_refused():
    lines = ["a0: &a0 [x, x]"] + [f"a{i}: &a{i} [*a{i-1}, *a{i-1}]" for i in range(1, 60)]
    with pytest.raises(ConfigError, match="aliases"):
        load("\n".join(lines))


def test_missing_file_and_non_utf8(tmp_path):
    with pytest.raises(ConfigError, match="file not found"):
        load_yaml(tmp_path / "nope.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_bytes(b"a: \xff\xfe\n")
    with pytest.raises(ConfigError, match="not UTF-8"):
        load_yaml(bad)


def test_merge_keys_still_work():
    doc = load("base: &b {x: 1}\nchild:\n  <<: *b\n  y: 2\n")
    assert doc["child"] == {"x": 1, "y": 2}


def test_control_characters_are_a_config_error():
    with pytest.raises(ConfigError, match="special characters"):
        load("a: b\x07c\n")
