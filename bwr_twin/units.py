"""Unit conversions the reclaim's tonnage needs: the twin computes in SI (m^3, kg, s) and
reports tonnes and t/h."""

SECONDS_PER_HOUR = 3600.0
KG_PER_T = 1000.0
