from pathlib import Path

import pytest

from atemr.config import Config, load_config, to_dict
from atemr.errors import ConfigError


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "robot.yaml"
    path.write_text(text)
    return path


def test_defaults():
    config = load_config(environ={})
    assert config == Config()
    assert config.simulation is True
    assert config.can.interface == "virtual" and config.can.bitrate == 1_000_000


def test_precedence_default_file_env_argument(tmp_path):
    path = write(tmp_path, "sim:\n  seed: 1\n  world: depot\ncan:\n  channel: file-chan\n")
    env = {"ATEMR_SIM__SEED": "2", "ATEMR_CAN__CHANNEL": "env-chan"}
    config = load_config(path, environ=env, overrides={"sim.seed": 3, "can.channel": None})
    assert config.sim.seed == 3  # argument beats env
    assert config.can.channel == "env-chan"  # env beats file; None argument does not override
    assert config.sim.world == "depot"  # file beats default
    assert config.sim.speed == 1.0  # default


def test_config_file_from_environment(tmp_path):
    path = write(tmp_path, "log_level: DEBUG\n")
    assert load_config(environ={"ATEMR_CONFIG": str(path)}).log_level == "DEBUG"


def test_env_values_are_parsed_to_the_field_type():
    config = load_config(environ={"ATEMR_SIMULATION": "false", "ATEMR_SIM__SPEED": "2.5", "ATEMR_DATA_DIR": "/tmp/x"})
    assert config.simulation is False and config.sim.speed == 2.5 and config.data_dir == Path("/tmp/x")


def test_unknown_key_in_file_names_file_line_column_and_suggests(tmp_path):
    path = write(tmp_path, "sim:\n  seed: 1\n  wrold: studio\n")
    with pytest.raises(ConfigError) as err:
        load_config(path, environ={})
    e = err.value
    assert (e.file, e.line, e.column, e.path) == (str(path), 3, 3, "sim.wrold")
    assert "did you mean 'world'" in str(e)


def test_wrong_type_in_file_points_at_the_value(tmp_path):
    path = write(tmp_path, "sim:\n  seed: lots\n")
    with pytest.raises(ConfigError) as err:
        load_config(path, environ={})
    assert (err.value.line, err.value.column) == (2, 9)
    assert "expected an integer, got 'lots'" in str(err.value)


def test_bounds_are_checked(tmp_path):
    with pytest.raises(ConfigError, match=r"must be at least 0\.01"):
        load_config(write(tmp_path, "sim: {speed: 0}\n"), environ={})
    with pytest.raises(ConfigError, match="one of"):
        load_config(write(tmp_path, "log_level: LOUD\n"), environ={})


def test_a_section_must_be_a_mapping(tmp_path):
    with pytest.raises(ConfigError, match="expected a mapping") as err:
        load_config(write(tmp_path, "sim: 3\n"), environ={})
    assert err.value.line == 1


def test_bad_env_value_names_the_variable():
    with pytest.raises(ConfigError) as err:
        load_config(environ={"ATEMR_SIM__SEED": "abc"})
    assert "environment ATEMR_SIM__SEED" in str(err.value)


def test_unknown_env_variable_is_an_error_with_a_suggestion():
    with pytest.raises(ConfigError, match="ATEMR_SIM__SEED"):
        load_config(environ={"ATEMR_SIM__SEDE": "1"})


def test_the_launchers_and_the_test_suites_variables_are_not_configuration():
    environ = {"ATEMR_PYTHON": "python3.11", "ATEMR_TEST_SOAK": "1", "ATEMR_TEST_HYPOTHESIS": "explore",
               "ATEMR_SIM__SEED": "4"}
    assert load_config(environ=environ).sim.seed == 4


def test_default_data_dir_follows_xdg(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path))
    assert load_config(environ={}).data_dir == tmp_path / "atemr"


def test_bad_argument_names_the_option():
    with pytest.raises(ConfigError, match=r"argument sim\.speed"):
        load_config(environ={}, overrides={"sim.speed": -1.0})


def test_nan_is_not_a_number_here(tmp_path):
    with pytest.raises(ConfigError, match="finite"):
        load_config(write(tmp_path, "sim: {speed: .nan}\n"), environ={})


def test_empty_file_means_defaults(tmp_path):
    assert load_config(write(tmp_path, ""), environ={}) == Config(data_dir=Config().data_dir)


def test_to_dict_is_flat_and_plain():
    flat = to_dict(load_config(environ={}))
    assert flat["sim.seed"] == 0 and isinstance(flat["data_dir"], str)
