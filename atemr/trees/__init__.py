"""YAML → py_trees builder, behaviour registry, the Monitor and tree export."""
