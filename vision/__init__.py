"""Vision locators shared by all kinid methods."""
