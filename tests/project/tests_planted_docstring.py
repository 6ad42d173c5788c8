"""A planted docstring gap for ``test_docstrings.test_gap_check_can_fail``."""


def undocumented(x, y=1):
    """Add two numbers (neither parameter nor the return value is documented)."""
    return x + y
