"""Scenario files: pydantic models, YAML loading and friendly validation errors."""
