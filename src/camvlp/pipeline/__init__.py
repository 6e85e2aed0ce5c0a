"""The locator, in stage order: detect -> stripes (row profiles) -> decode / frequency -> pose,
and ``locate`` that runs them on one photograph."""
