"""The pile's shape: its surface on a height grid above the yard's ground (surface, ground), the
slump of faces steeper than the angle of repose (relaxation) and the bucket wheel's cut
(cutting), which planning and the stockpile both build on; and a stacked pile's file, checked
as it is read (stacked_file)."""
