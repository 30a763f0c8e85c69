"""Fixtures for the simulator tests: ideal wheels (a test double of the motor protocol) and small worlds."""

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from PIL import Image


class IdealWheel:
    """Satisfies `WheelMotor`: the speed follows the command at once (no dynamics), so distances are exact."""

    def __init__(self) -> None:
        self.command = 0.0
        self.speed_radps = 0.0
        self.steps = 0

    def set_speed(self, speed_radps: float) -> None:
        self.command = speed_radps

    def step(self, dt_s: float) -> None:
        self.speed_radps = self.command
        self.steps += 1


@pytest.fixture
def ideal_wheels() -> tuple[IdealWheel, IdealWheel]:
    return IdealWheel(), IdealWheel()


@pytest.fixture
def make_world(tmp_path: Path) -> Callable[..., Path]:
    """Write a world: a walled rectangular room (``width_m`` x ``height_m``, 5 cm cells, origin (0, 0)) plus
    the given world-file body; returns the world file's path."""

    def make(body: str = "", width_m: float = 6.0, height_m: float = 4.0, name: str = "room") -> Path:
        res = 0.05
        rows, cols = round(height_m / res), round(width_m / res)
        pixels = np.full((rows, cols), 254, dtype=np.uint8)
        pixels[:2, :] = pixels[-2:, :] = pixels[:, :2] = pixels[:, -2:] = 0  # 10 cm walls
        Image.fromarray(pixels).save(tmp_path / f"{name}.pgm", format="PPM")
        (tmp_path / f"{name}.yaml").write_text(
            f"image: {name}.pgm\nresolution: {res}\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
            "occupied_thresh: 0.65\nfree_thresh: 0.196\n"
        )
        world = tmp_path / f"{name}.world.yaml"
        world.write_text(f"name: {name}\nmap: {name}.yaml\n{body}")
        return world

    return make
