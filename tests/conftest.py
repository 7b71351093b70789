"""Test configuration: float64 everywhere (as the CLI sets it)."""

import beamcontact

beamcontact.enable_x64()
