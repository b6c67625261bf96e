"""Configuration: scene files (typed, validated, with `extends` and overrides) and sweep files, the
plug-in classes a scene names (plugins) and the calls that keep their failures their own (plugin_calls)."""
