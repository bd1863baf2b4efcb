"""The project's simulated motors and hexacopter."""
