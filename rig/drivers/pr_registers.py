"""Register map of a Leadshine-style Modbus RTU stepper/servo drive in PR mode.

One table, so that a drive whose manual differs is supported by editing this file
only. Addresses from the Leadshine PR-mode documentation as summarised in
shared/REFERENCE.md §4; the read-back registers (status, command position, alarm)
follow the same family of drives. Check your drive's manual.
"""

from __future__ import annotations

PULSES_PER_REV = 0x0001  # setup: pulses per motor revolution

PR0_MODE = 0x6200  # path 0 motion mode
PR0_POS_HIGH = 0x6201  # path 0 target position, int32 high word first
PR0_POS_LOW = 0x6202
PR0_VELOCITY_RPM = 0x6203
PR0_ACCEL_MS = 0x6204  # ms per 1000 rpm
PR0_DECEL_MS = 0x6205

MODE_ABSOLUTE = 0x0001
MODE_RELATIVE = 0x0041
MODE_VELOCITY = 0x0002

PR_CONTROL = 0x6002  # write: command; read: path status
CTRL_TRIGGER_PR0 = 0x0010
CTRL_HOME = 0x0020
CTRL_SET_ZERO = 0x0021
CTRL_EMERGENCY_STOP = 0x0040
STATUS_RUNNING = 0x0100  # read-back bit: a path (or homing) is executing
STATUS_HOMED = 0x0001  # read-back bit: a homing has completed since power-up

COMMAND_POS_HIGH = 0x602A  # command position, int32 high word first
COMMAND_POS_LOW = 0x602B

ALARM_CODE = 0x2203  # 0 when no alarm

JOG = 0x1801
JOG_CW = 0x4001
JOG_CCW = 0x4002
