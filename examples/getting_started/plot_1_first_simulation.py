"""
First simulation
================

A run.
"""
import vsj
print(vsj.__version__)
