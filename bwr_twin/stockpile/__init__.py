"""The stockpile the bucket wheel digs: its surface on a height grid, the cut, the digging load."""
