"""Configuration: scene files (typed, validated, with `extends` and overrides) and sweep files."""
