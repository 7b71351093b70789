"""From a validated case (io/case.py) to the model objects the solvers take: the discrete
model, the contact problem, and the checks that need the discretisation. The only layer
below the runner that reads the case schema."""
