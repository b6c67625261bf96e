"""Planning: the desired joint trajectory through the scene's via points (trajectory), or a
bench reclaim planned from the pile (bench: the planner; plan: what it plans; follower: each
run's reference along it, one control period at a time)."""
