"""Examples built on mwjax (importable from the repository root, e.g. `examples.train_mt_ppo`)."""
