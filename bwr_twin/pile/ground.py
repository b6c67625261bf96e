"""Where the yard's ground lies: the pile, its surveys and its layers stand on it."""

YARD_FLOOR = 0.0  # m, world Z of the ground the pile stands on: nothing lies, or is dug, below it
