"""USB plumbing of the host driver: a device-side function model (descriptors + endpoint
callbacks) and pyusb backends that reach one in-process or over USB/IP.

``multisonar.usb`` is not the pyusb package ``usb`` (absolute imports keep them apart).
"""
