"""Live streams: sources (stdin CSV, ATI Net F/T, LSL), the streamed outputs and the browser dashboard.

- :mod:`~phri_spring.io.live.dashboard` ``phri live --dashboard``: a local web page of the pressure map (docs/live.md)
- :mod:`~phri_spring.io.live.netft` ATI Net F/T "raw data transfer" (RDT) over UDP: a small client (docs/live.md)
- :mod:`~phri_spring.io.live.outputs` Outputs of ``phri live`` (docs/live.md): the forces table streamed to disk, LSL outlets
- :mod:`~phri_spring.io.live.sources` Live wrench sources of ``phri live`` (docs/live.md): standard input, Net F/T, LSL
"""
