"""Planning: the desired joint trajectory through the scene's via points."""
