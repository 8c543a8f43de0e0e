"""The paper's studies as declarative scenario sets (TOML under ``experiments/``) and the campaign runner."""
