"""silpose.model"""
