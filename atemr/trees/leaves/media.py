"""Leaves that use the camera."""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import py_trees

from atemr.errors import AtemrError
from atemr.trees.behaviours import Leaf, behaviours

Status = py_trees.common.Status

_LABEL = re.compile(r"^[A-Za-z0-9_.-]{1,64}$")


@dataclass(frozen=True)
class CaptureImageParams:
    label: str = field(default="capture", metadata={"help": "file-name-safe label: letters, digits, _ . -"})

    def validate(self) -> None:
        if not _LABEL.match(self.label):
            raise ValueError(f"label must be 1-64 letters, digits, '_', '.' or '-', got {self.label!r}")


@behaviours.register("CaptureImage")
class CaptureImage(Leaf):
    """Store one camera frame labelled ``label``; SUCCESS with where it went, FAILURE if the camera fails."""

    Params = CaptureImageParams
    summary = "store one camera image"

    def initialise(self) -> None:
        self.saved_as: str | None = None

    def update(self) -> py_trees.common.Status:
        try:
            self.saved_as = self.ctx.port.capture_image(self.params.label)
        except AtemrError as exc:
            return self.fail(f"capture failed: {exc}")
        self.feedback_message = f"saved {self.saved_as}"
        return Status.SUCCESS
