"""silpose.datagen"""
