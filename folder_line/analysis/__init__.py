"""Analysis of a recorded run: reading a bag, replaying the supervisor, figures, report."""
