"""virtual_sensing"""
