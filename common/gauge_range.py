"""The largest force and torque limits any file may ask for: a six-axis gauge's full scale.

The FT300 reports forces as int16 / 100 N and torques as int16 / 1000 N·m (its manual, as
rig/drivers/ft300.py decodes them), so it saturates at ±327.67 N and ±32 767 N·mm; its rated
range is ±300 N and ±30 N·m. A limit above the gauge's full scale can never trip (a NaN limit
once let z press on with the gauge pinned at 327 N); a tactile gel is ruined far below.
The rig config's [safety] and a protocol's [limits] are both checked against these.
"""

MAX_FORCE_LIMIT_N = 300.0
MAX_TORQUE_LIMIT_NMM = 30000.0
