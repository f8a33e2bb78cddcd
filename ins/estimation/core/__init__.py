"""The filter core: error-state layout and model (:mod:`.error_model`), the measurement
protocol and Kalman update (:mod:`.measurements`), the updates at a node
(:mod:`.updates`), the lever arm (:mod:`.lever_arm`), the forward filter
(:mod:`.filter`, :mod:`.filter_settings`, :mod:`.filter_stores`) and the RTS smoother
(:mod:`.smoother`), with their compiled kernels.

Imports nothing else of :mod:`ins.estimation`.
"""
