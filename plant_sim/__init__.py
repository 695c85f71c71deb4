"""Plant simulators: the 4.8 MW benchmark turbine, the 9-turbine farm and the hydrostatic turbine.

Pure numpy: nothing here imports a transport. The Zenoh edge of the plant process is ``windwarden.live.plant_node``.
"""
