"""Optional services a board composes onto an endpoint (see endpoint.Endpoint.add)."""
