"""The tree family (cocta, ncocta): connected coverage of a tree, one step barrier a step."""
