"""What the tests share: helpers and strategies (helpers), independent reference
implementations (reference_*), a Net F/T emulator and the docs-block runner."""
