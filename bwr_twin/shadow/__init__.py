"""The shadow: the twin run beside a machine from its measured drive forces, its residuals, and
the faults they reveal (docs/shadow.md)."""
