"""What the machine is: the board's fixed facts (hardware), the machine profile
(MachineConfig, profile.toml) and where the user's files live.
"""
