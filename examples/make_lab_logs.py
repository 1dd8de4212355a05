"""Write examples/wrench_log.tdms and examples/wrench_log.mat from examples/wrench_log.csv.

The same SYNTHETIC I-Act-like log (see make_wrench_log.py) in the lab's own
formats, as ``phri simulate`` reads them (docs/model.md section 7):

- ``wrench_log.tdms`` (National Instruments TDMS, written with npTDMS): group
  ``wrench`` with channels ``Fx Fy Fz`` [N] and ``Mx My Mz`` [N*m] as
  waveforms (``wf_start_offset`` 0 s, ``wf_increment`` 0.01 s: 100 Hz), no
  time channel, as NI acquisition software writes them;
- ``wrench_log.mat`` (MATLAB v5, written with scipy): a struct ``log`` with
  one vector per column, ``time`` [s] included (read it with ``--group log``).

The values are the CSV's, parsed by phri-spring's own reader, so the forces
computed from the three files are identical to the last bit. Needs the ``lab``
extra (npTDMS). Run from the repository root:

    python examples/make_lab_logs.py
"""

from pathlib import Path

import numpy as np

from phri_spring.io.logs import read_wrench_log

HERE = Path(__file__).resolve().parent
NAMES = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")


def write_tdms(path, time, wrench, *, group="wrench", time_channel=False):
    """Write a wrench log as TDMS waveforms (or with a ``time`` channel)."""
    from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

    inc = float(np.median(np.diff(time))) if len(time) > 1 else 1.0
    props = {"wf_start_offset": float(time[0]), "wf_increment": inc,
             "wf_samples": len(time), "unit_string": ""}
    channels = []
    if time_channel:
        channels.append(ChannelObject(group, "time", np.asarray(time, dtype=np.float64),
                                      properties={"unit_string": "s"}))
    for j, name in enumerate(NAMES):
        unit = "N" if name.startswith("F") else "N*m"
        channels.append(ChannelObject(group, name, np.ascontiguousarray(wrench[:, j]),
                                      properties={**props, "unit_string": unit}))
    with TdmsWriter(str(path)) as writer:
        writer.write_segment([RootObject({"description": "SYNTHETIC I-Act-like log made by "
                                          "examples/make_lab_logs.py"}),
                              GroupObject(group), *channels])


def write_mat(path, time, wrench, *, struct="log"):
    """Write a wrench log as MATLAB v5: one column vector per column, in a struct (or not)."""
    import scipy.io

    columns = {"time": np.asarray(time, dtype=np.float64)}
    columns.update({name: np.ascontiguousarray(wrench[:, j]) for j, name in enumerate(NAMES)})
    data = {struct: columns} if struct else columns
    scipy.io.savemat(str(path), data, do_compression=True, oned_as="column")


def main() -> None:
    time, wrench = read_wrench_log(HERE / "wrench_log.csv")
    write_tdms(HERE / "wrench_log.tdms", time, wrench)
    write_mat(HERE / "wrench_log.mat", time, wrench)
    print(f"wrote {HERE / 'wrench_log.tdms'} and {HERE / 'wrench_log.mat'} "
          f"({len(time)} samples)")


if __name__ == "__main__":
    main()
