"""Register map of a Leadshine RS-485 (Modbus RTU) stepper drive in PR (path) mode.

One table, so that a drive whose manual differs is supported by editing this file
only. It holds for Leadshine's RS-485 stepper drives with PR mode and their
STEPPERONLINE-branded twins, whose manuals (2022 editions) share these tables:

- [CS2RS] Leadshine CS2RS Series Modbus RS485 Closed Loop Stepper Drive User Manual,
  "Immediate Trigger" (p. 43; §5.5.4 in the identical STEPPERONLINE CLRS manual):
  PR0 is eight registers from 0x6200, Pr9.07 (0x6207) "is mapped to Pr8.02" (0x6002),
  "writing value 0x10 to it will trigger PR0 motion immediately"; the worked
  example ``07 10 62 00 00 08 10 ... 00 10 8D 50`` → ``07 10 62 00 00 08 DE 11``.
- [RS485 §4.3.1] STEPPERONLINE Modbus RS485 Stepper Drive User Manual, "Basic
  Parameters": 0x0001 = Pr0.00 pulses/revolution (200–51200, default 10000).
- [RS485 §4.3.4] the same manual and Leadshine's iEM-RS manual, "Status Monitoring
  Parameters": 0x1003 motion state (bit0 fault, bit1 enabled, bit2 running, bit4
  command completed, bit5 path completed, bit6 homing completed); 0x1012/0x1013
  profile (command) position and 0x1014/0x1015 feedback position, pulses, high word first.
- [iEM-RS §4.3.5] "Control Word": 0x1801 write 0x4001 / 0x4002 jog CW / CCW.

Not in the manual pages at hand (kept, marked ASSUMED below): the other 0x6002
commands (0x20 homing, 0x21 set zero, 0x40 emergency stop; an open Leadshine driver,
github.com/yizhongzhang1989/robot_dc ``leadshine_motor``, writes the same values),
the mode codes beyond 0x0001, the ramp unit, and the alarm code register 0x2203.
0x602A/0x602B (this project's old position read-back) and 0x602C (that open driver's)
appear in no manual table found: the driver reads 0x1012 and 0x1003 instead.
"""

from __future__ import annotations

PULSES_PER_REV = 0x0001  # Pr0.00 pulses per motor revolution [RS485 §4.3.1]

# Software travel limits. ASSUMED from three open drivers that agree (none of the manual pages at
# hand has the Pr8 table): Pr8.00 (0x6000) PR control setting, bit1 "software limit valid";
# Pr8.06/Pr8.07 (0x6006/0x6007) positive limit and Pr8.08/Pr8.09 (0x6008/0x6009) negative limit,
# int32 pulses, high word first. A path that would pass an enabled limit stops at it.
PR_CONTROL_SETTING = 0x6000  # Pr8.00
SOFT_LIMIT_ENABLE = 0x0002  # its bit1
SOFT_LIMIT_POS_HIGH = 0x6006  # Pr8.06
SOFT_LIMIT_POS_LOW = 0x6007
SOFT_LIMIT_NEG_HIGH = 0x6008  # Pr8.08
SOFT_LIMIT_NEG_LOW = 0x6009
INT32_MIN, INT32_MAX = -(2**31), 2**31 - 1

# Path 0, written in one function-16 request of PR0_LENGTH registers [CS2RS].
PR0_MODE = 0x6200  # Pr9.00
PR0_POS_HIGH = 0x6201  # Pr9.01 target, pulses, int32 high word first
PR0_POS_LOW = 0x6202  # Pr9.02
PR0_VELOCITY_RPM = 0x6203  # Pr9.03
PR0_ACCEL_MS = 0x6204  # Pr9.04; ASSUMED unit: ms per 1000 rpm
PR0_DECEL_MS = 0x6205  # Pr9.05
PR0_DELAY_MS = 0x6206  # Pr9.06 delay (pause) after the path
PR0_TRIGGER = 0x6207  # Pr9.07, mapped to PR_CONTROL: 0x10 runs PR0 at once
PR0_LENGTH = 8

MODE_ABSOLUTE = 0x0001  # position move [CS2RS example]
MODE_RELATIVE = 0x0041  # ASSUMED (the robot_dc driver uses it)
MODE_VELOCITY = 0x0002  # ASSUMED (the robot_dc driver uses it)

PR_CONTROL = 0x6002  # Pr8.02 trigger register (write)
CTRL_TRIGGER_PR0 = 0x0010  # [CS2RS]
CTRL_HOME = 0x0020  # ASSUMED
CTRL_SET_ZERO = 0x0021  # ASSUMED
CTRL_EMERGENCY_STOP = 0x0040  # ASSUMED

MOTION_STATE = 0x1003  # [RS485 §4.3.4], read only
STATE_FAULT = 0x0001  # bit0
STATE_ENABLED = 0x0002  # bit1
STATE_RUNNING = 0x0004  # bit2
STATE_COMMAND_DONE = 0x0010  # bit4
STATE_PATH_DONE = 0x0020  # bit5
STATE_HOMED = 0x0040  # bit6: a homing has completed

COMMAND_POS_HIGH = 0x1012  # profile (command) position, pulses, int32 high word first [RS485 §4.3.4]
COMMAND_POS_LOW = 0x1013
FEEDBACK_POS_HIGH = 0x1014  # feedback (encoder) position [iEM-RS §4.3.4]
FEEDBACK_POS_LOW = 0x1015

ALARM_CODE = 0x2203  # ASSUMED: read only when STATE_FAULT is set

JOG = 0x1801  # control word [iEM-RS §4.3.5]
JOG_CW = 0x4001
JOG_CCW = 0x4002
