"""OPC UA building blocks shared by the twin's server and the shadow's: nodes with the node ids
the caller chooses, Part 8 analog items with their units and ranges, and Part 9 conditions with
ConditionRefresh."""
