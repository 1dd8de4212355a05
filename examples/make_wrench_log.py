"""Write examples/wrench_log.csv: a SYNTHETIC I-Act-like wrench log (fixed seed).

The arm is loaded horizontally (+z of the load cell) with 0, 11.1, 33.4 and
55.6 N steps held 8 s each, then unloaded, at 100 Hz, with Gaussian sensor
noise (0.3 N, 0.01 N*m), as the Harmony load cell of configs/harmony_upper_arm.yaml
would read it. The same text is what ``phri init --example DIR`` writes from an
installed package (phri_spring.workflows.starter). Run from the repository root:

    python examples/make_wrench_log.py
"""

from pathlib import Path

from phri_spring.workflows.starter import EXAMPLE_LOG, example_log_text

HERE = Path(__file__).resolve().parent


def main() -> None:
    text = example_log_text()
    out = HERE / EXAMPLE_LOG
    out.write_text(text, encoding="utf-8")
    print(f"wrote {out} ({text.count(chr(10)) - 2} samples)")


if __name__ == "__main__":
    main()
