"""The stockpile the bucket wheel digs: its material in layers and grades, the deposits that stack
it, the digging load, the stacking and reclaim of a run; its shape is bwr_twin.pile."""
