"""plant_sim"""
