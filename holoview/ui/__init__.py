"""The Qt interface. The only holoview package that imports Qt: it draws and
forwards commands; processing and acquisition do the work."""
