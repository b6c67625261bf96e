"""The pile's shape: its surface on a height grid (surface), the slump of faces steeper than the
angle of repose (relaxation) and the bucket wheel's cut (cutting), which planning and the
stockpile both build on."""
