"""A servo's EEPROM kept in a file between simulator runs, as a real servo keeps it unpowered."""

from __future__ import annotations

import os
from pathlib import Path

from firmware_sim.control_table import EEPROM_END, Register
from firmware_sim.servo import Servo


class EepromFile:
    """The EEPROM file ``directory/servo-SLOT.eeprom`` of the servo in ``slot`` (not its ID)."""

    def __init__(self, directory: str | os.PathLike, slot: int) -> None:
        self.path = Path(directory) / f"servo-{slot}.eeprom"
        self._saved = b""

    def load(self, servo: Servo) -> bool:
        """Put the file's EEPROM into ``servo`` (True), or leave it factory-fresh (False);
        ValueError if the file is not an EEPROM of this servo's model."""
        if not self.path.exists():
            return False
        data = self.path.read_bytes()
        number = servo.value(Register.MODEL_NUMBER)
        if len(data) != EEPROM_END or int.from_bytes(data[:2], "little") != number:
            raise ValueError(
                f"{self.path} is not the EEPROM of a {servo.model.title} ({EEPROM_END} bytes "
                f"starting with model number {number}); delete it to start factory-fresh"
            )
        servo.memory[:EEPROM_END] = data
        servo.reboot()  # a power-up with this EEPROM: RAM at its defaults
        self._saved = data
        return True

    def save(self, servo: Servo) -> None:
        """Write the EEPROM back if it changed since the last load or save."""
        data = bytes(servo.memory[:EEPROM_END])
        if data == self._saved:
            return
        self.path.parent.mkdir(parents=True, exist_ok=True)
        partial = self.path.with_suffix(".partial")
        partial.write_bytes(data)
        os.replace(partial, self.path)  # a crash never leaves half an EEPROM
        self._saved = data
