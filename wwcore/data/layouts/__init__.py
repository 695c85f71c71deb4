"""Wind-farm layout files: ``<name>.csv`` with turbine,x_m,y_m and a ``# rotor_diameter_m:`` header line."""
