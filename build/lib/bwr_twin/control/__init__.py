"""Control: the fuzzy rule base and its surface, the controller's belief (M, bias), the control law."""
