"""Reference oracles: independent (numpy) statements of rules the production code computes
in loops, for the tests to compare the loops against. Nothing in production imports them."""
