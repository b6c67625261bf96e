"""The machine drawn from its MJCF: its visual geoms as triangle meshes, posed by its kinematics,
and shown in a viser scene."""
