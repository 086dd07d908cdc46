"""The FastCS side: configuration, PV naming, type mapping, launch."""
