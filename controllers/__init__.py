"""Control laws as plain classes (``reset()``, ``step(t, y, r) -> u``) and the controller node."""
