"""The operator: the scenario's schedule of set-point changes, published on the bus."""
