"""The mean phase of every frame, and the depths and rates that follow from it.

Read in this order: :mod:`.carrier_probe` (carrier values of every frame without a full
FFT), :mod:`.phase_series` (unwrapping in time, the aliasing check),
:mod:`.frame_gaps` (the frame intervals a step spans where frames were lost),
:mod:`.joint_estimation` and :mod:`.joint_series` (one height and one reference-arm
phase a frame from every peak), :mod:`.depth_series` (depths per peak and fused),
:mod:`.rate_fits` (rates with honest standard errors, volumes).
"""
