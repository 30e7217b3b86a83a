"""Studies of the cam drive (seed 002): constant armature voltage with the seed's discrete
scheme against an accurate solver (:mod:`.voltage`, results in :mod:`.voltage_result`), and
speed estimation from shaft-encoder counts (:mod:`.estimation`)."""
