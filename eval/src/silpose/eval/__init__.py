"""silpose.eval"""
